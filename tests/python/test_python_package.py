"""The Python package (src/python, ``import spatial_dynamics``) against Pinocchio.

Every function of ``spatial_dynamics.Model`` on one random state per case, on the robots of the
reference suite (pinocchio_cases: UR5, Panda, Kinova with its continuous joints, Solo12 and
ANYmal on floating bases, Panda with its finger mimic followed), coordinates mapped by name as
in test_pinocchio_reference (``Mapping`` from our ``model --json``): rnea, gravity,
forward_dynamics (every method), mass_matrix, frame_placement and frame_jacobian (three links,
three references), center_of_mass, rnea_derivatives and aba_derivatives (Pinocchio's M and M⁻¹
symmetrised from their upper triangle), each to TOLERANCE relative to the reference's largest
entry. Then: N states as 2-D arrays equal the single calls row by row, bit for bit; errors
raise DynamicsError, a ValueError, naming the coordinate, frame, argument or row; masked arrays
raise TypeError naming the argument (or its item, inside a list); a batch runs with the GIL released, from the inputs as
they were at the call while another thread writes them; the stubs
(src/python/spatial_dynamics.pyi) name exactly the module's public names and Model's, with the
module's parameters.

The package is installed into the venv by launch_scripts/setup_python_env.sh.
"""

from __future__ import annotations

import ast
import copy
import inspect
import json
import os
import pickle
import sys
import threading
import time
import zlib

import numpy as np
import pinocchio as pin
import pytest

from pinocchio_cases import (
    REPO,
    Case,
    Mapping,
    _sym,
    binary_path,
    build_reference,
    require_binary,
    run_command,
    sample_state,
    urdf_path,
)
from test_pinocchio_reference import CASES

try:
    import spatial_dynamics as sd
except ImportError as exc:  # a required test: say how to get the package
    pytest.fail(
        f"cannot import spatial_dynamics ({exc}): launch_scripts/setup_python_env.sh installs it",
        pytrace=False,
    )

TOLERANCE = 1e-9
SEED = 2028
STUBS = REPO / "src" / "python" / "spatial_dynamics.pyi"
PACKAGE_CASES = tuple(
    c for c in CASES if c.name in ("ur5", "panda", "kinova", "solo12", "anymal", "panda_mimic")
)
REFERENCES = {
    "world": pin.ReferenceFrame.WORLD,
    "local": pin.ReferenceFrame.LOCAL,
    "local_world_aligned": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
}


def close(ours, ref, what):
    ours, ref = np.asarray(ours, dtype=float), np.asarray(ref, dtype=float)
    assert ours.shape == ref.shape, f"{what}: shape {ours.shape}, reference {ref.shape}"
    scale = max(1.0, float(np.max(np.abs(ref)))) if ref.size else 1.0
    err = float(np.max(np.abs(ours - ref))) / scale if ref.size else 0.0
    assert err <= TOLERANCE, f"{what}: relative difference {err:.3e} > {TOLERANCE:g}\nours {ours}\nref  {ref}"


class Setup:
    """Our model, Pinocchio's, the mapping between them and one random state (both conventions)."""

    def __init__(self, case: Case):
        require_binary()
        path = urdf_path(case)
        self.case, self.ref = case, build_reference(case, path)
        self.model = sd.Model.from_urdf(str(path), floating_base=case.floating, ignore_mimic=not case.mimic)
        out = run_command([str(binary_path()), "model", "--urdf", str(path), *case.our_flags(), "--json"])
        assert out.returncode == 0, out.stderr
        self.map = Mapping.build(json.loads(out.stdout), self.ref)
        rng = np.random.default_rng(SEED ^ zlib.crc32(case.name.encode()))
        q, self.v, self.a, self.tau = sample_state(self.ref, rng)
        self.q_ours = self.map.q_to_ours(q)
        self.q = self.map.q_to_ref(self.q_ours)
        self.v_ours, self.a_ours, self.tau_ours = (self.map.v_to_ours(x) for x in (self.v, self.a, self.tau))

    def cols(self, matrix):
        """A reference matrix's columns in our velocity order."""
        return np.asarray(matrix)[:, self.map.perm]

    def square(self, matrix):
        """A reference nv × nv matrix in our order (rows and columns)."""
        return np.asarray(matrix)[np.ix_(self.map.perm, self.map.perm)]


_SETUPS: dict = {}


def setup_of(case: Case) -> Setup:
    if case not in _SETUPS:
        _SETUPS[case] = Setup(case)
    return _SETUPS[case]


@pytest.fixture(params=PACKAGE_CASES, ids=[c.name for c in PACKAGE_CASES])
def s(request) -> Setup:
    return setup_of(request.param)


def test_coordinates_are_the_binary_s(s):
    m = s.model
    assert (m.nq, m.nv) == (s.map.our_nq, s.map.our_nv)
    assert len(m.v_names) == m.nv and len(set(m.v_names)) == m.nv
    assert all(isinstance(n, str) for n in m.link_names) and m.link_names


def test_dynamics_match_pinocchio(s):
    m, ref, name = s.model, s.ref, s.case.name
    close(m.rnea(s.q_ours, s.v_ours, s.a_ours), s.map.v_to_ours(ref.rnea(s.q, s.v, s.a)), f"{name} rnea")
    close(m.gravity(s.q_ours), s.map.v_to_ours(ref.gravity(s.q)), f"{name} gravity")
    close(m.mass_matrix(s.q_ours), s.square(ref.mass_matrix(s.q)), f"{name} mass_matrix")
    want = s.map.v_to_ours(ref.forward_dynamics(s.q, s.v, s.tau))
    close(m.forward_dynamics(s.q_ours, s.v_ours, s.tau_ours), want, f"{name} forward_dynamics")
    methods = ("crba", "rnea_columns") if ref.has_mimic else ("aba", "crba", "rnea_columns")
    for method in methods:
        got = m.forward_dynamics(s.q_ours, s.v_ours, s.tau_ours, method=method)
        close(got, want, f"{name} forward_dynamics {method}")
    # method=None is the model's own choice, bit for bit.
    chosen = m.forward_dynamics(s.q_ours, s.v_ours, s.tau_ours, method=m.forward_dynamics_method)
    assert np.array_equal(m.forward_dynamics(s.q_ours, s.v_ours, s.tau_ours), chosen)


def frames_checked(s: Setup):
    """Three links that Pinocchio also has as frames: the first, middle and last such."""
    names = [n for n in s.model.link_names if s.ref.model.existFrame(n)]
    assert names, s.case.name
    return sorted({names[0], names[len(names) // 2], names[-1]})


def test_frames_match_pinocchio(s):
    model, data = s.ref.model, s.ref.data
    pin.framesForwardKinematics(model, data, s.q)
    for frame in frames_checked(s):
        fid = model.getFrameId(frame)
        translation, rotation = s.model.frame_placement(s.q_ours, frame)
        close(translation, data.oMf[fid].translation, f"{s.case.name} {frame} translation")
        close(rotation, data.oMf[fid].rotation, f"{s.case.name} {frame} rotation")
        for reference, pin_reference in REFERENCES.items():
            want = s.cols(pin.computeFrameJacobian(model, data, s.q, fid, pin_reference))
            close(s.model.frame_jacobian(s.q_ours, frame, reference), want, f"{s.case.name} {frame} {reference}")
    world = s.model.frame_jacobian(s.q_ours, frame)
    assert np.array_equal(world, s.model.frame_jacobian(s.q_ours, frame, reference="world"))


def test_center_of_mass_matches_pinocchio(s):
    model, data = s.ref.model, s.ref.data
    com = pin.centerOfMass(model, data, s.q)
    jacobian = pin.jacobianCenterOfMass(model, data, s.q)
    mass, position, j = s.model.center_of_mass(s.q_ours)
    assert isinstance(mass, float)
    close(mass, data.mass[0], f"{s.case.name} mass")
    close(position, com, f"{s.case.name} com")
    close(j, s.cols(jacobian), f"{s.case.name} com jacobian")


def test_derivatives_match_pinocchio(s):
    if s.ref.has_mimic:
        pytest.skip("Pinocchio's derivatives do not take mimic joints")
    model, data, name = s.ref.model, s.ref.data, s.case.name
    dq, dv, da = (np.array(x) for x in pin.computeRNEADerivatives(model, data, s.q, s.v, s.a))
    ours = s.model.rnea_derivatives(s.q_ours, s.v_ours, s.a_ours)
    for got, want, what in zip(ours, (dq, dv, _sym(da)), ("dtau_dq", "dtau_dv", "M")):
        close(got, s.square(want), f"{name} {what}")
    dq, dv, dtau = (np.array(x) for x in pin.computeABADerivatives(model, data, s.q, s.v, s.tau))
    ours = s.model.aba_derivatives(s.q_ours, s.v_ours, s.tau_ours)
    for got, want, what in zip(ours, (dq, dv, _sym(dtau)), ("ddq_dq", "ddq_dv", "Minv")):
        close(got, s.square(want), f"{name} {what}")


def calls(s: Setup):
    """Every function as (name, arguments per state, call)."""
    m, frame = s.model, s.model.link_names[-1]
    return (
        ("rnea", 3, m.rnea),
        ("gravity", 1, m.gravity),
        ("forward_dynamics", 3, m.forward_dynamics),
        ("mass_matrix", 1, m.mass_matrix),
        ("frame_placement", 1, lambda q: m.frame_placement(q, frame)),
        ("frame_jacobian", 1, lambda q: m.frame_jacobian(q, frame, "local")),
        ("center_of_mass", 1, m.center_of_mass),
        ("rnea_derivatives", 3, m.rnea_derivatives),
        ("aba_derivatives", 3, m.aba_derivatives),
    )


def test_batches_equal_single_calls_bit_for_bit(s):
    """Seven states (more than the threads, not a multiple of two) as 2-D arrays: each row of
    each result is the single call's on that row, bit for bit."""
    rng = np.random.default_rng(7)
    rows = 7
    qs = np.stack([s.map.q_to_ours(sample_state(s.ref, rng)[0]) for _ in range(rows)])
    vs, as_ = rng.standard_normal((2, rows, s.model.nv))
    for name, arity, call in calls(s):
        if name in ("rnea_derivatives", "aba_derivatives") and s.ref.has_mimic:
            continue
        args = (qs, vs, as_)[:arity]
        batch = call(*args)
        batch = batch if isinstance(batch, tuple) else (batch,)
        for i in range(rows):
            single = call(*(x[i] for x in args))
            single = single if isinstance(single, tuple) else (single,)
            for b, one in zip(batch, single):
                assert b.shape[0] == rows, name
                assert np.array_equal(b[i], one), f"{s.case.name} {name} row {i}"
    # No states: empty results of the stacked shapes.
    assert s.model.gravity(np.zeros((0, s.model.nq))).shape == (0, s.model.nv)


def test_lists_and_other_dtypes_are_converted():
    s = setup_of(PACKAGE_CASES[0])
    m, q = s.model, s.q_ours
    want = m.gravity(q)
    assert np.array_equal(m.gravity(q.tolist()), want)
    assert np.array_equal(m.gravity(np.asfortranarray(np.stack([q, q]))[:, :]), np.stack([want, want]))
    assert np.array_equal(m.gravity(np.stack([q, q])[::2]), want[None, :])
    assert m.gravity(np.zeros(m.nq, dtype=np.int64)).dtype == np.float64


def test_errors_raise_dynamics_error_naming_the_fault():
    s = setup_of(PACKAGE_CASES[0])
    m, q, v = s.model, s.q_ours.copy(), s.v_ours
    assert issubclass(sd.DynamicsError, ValueError)
    q[2] = np.nan
    with pytest.raises(sd.DynamicsError, match=rf"q\[2\] \({m.v_names[2]}\) is NaN"):
        m.gravity(q)
    with pytest.raises(ValueError, match=r"row 1: q\[2\]"):
        m.rnea(np.stack([s.q_ours, q]), np.stack([v, v]), np.stack([v, v]))
    with pytest.raises(sd.DynamicsError, match="no link named 'no_such_link'"):
        m.frame_jacobian(s.q_ours, "no_such_link")
    with pytest.raises(sd.DynamicsError, match="no link named 'no_such_link'"):
        m.frame_placement(s.q_ours, "no_such_link")
    with pytest.raises(sd.DynamicsError, match="reference 'global' is none of"):
        m.frame_jacobian(s.q_ours, m.link_names[-1], "global")
    with pytest.raises(sd.DynamicsError, match=rf"v has shape \({m.nv - 1},\), the model needs {m.nv}"):
        m.rnea(s.q_ours, v[:-1], v)
    with pytest.raises(sd.DynamicsError, match=r"tau has shape \(2, 2, 3\)"):
        m.forward_dynamics(s.q_ours, v, np.zeros((2, 2, 3)))
    with pytest.raises(sd.DynamicsError, match=r"a holds 2 states \(2-D\), q one state \(1-D\)"):
        m.rnea(s.q_ours, v, np.stack([v, v]))
    with pytest.raises(TypeError, match="^q must be real numbers"):
        m.gravity(["x"] * m.nq)
    with pytest.raises(sd.DynamicsError, match="q is not an array of numbers"):
        m.gravity([[0.0] * m.nq, [0.0]])
    with pytest.raises(sd.DynamicsError, match="unknown"):
        m.forward_dynamics(s.q_ours, v, v, method="newton")
    with pytest.raises(sd.DynamicsError, match="cannot parse the URDF"):
        sd.Model.from_urdf_string("<robot name='r'><link name='a'>")
    with pytest.raises(FileNotFoundError):
        sd.Model.from_urdf(str(REPO / "no_such_file.urdf"))


def test_a_long_batch_equals_single_calls_in_every_block():
    """2 501 states (many blocks of rows per thread, the last one short): every row of each
    result, one output or several, is the single call's on that row, bit for bit."""
    s = setup_of(PACKAGE_CASES[0])
    m, rng, rows = s.model, np.random.default_rng(11), 2501
    qs = np.stack([s.map.q_to_ours(sample_state(s.ref, rng)[0]) for _ in range(rows)])
    vs, as_ = rng.standard_normal((2, rows, m.nv))
    tau = m.rnea(qs, vs, as_)
    translation, rotation = m.frame_placement(qs, m.link_names[-1])
    for i in range(rows):
        assert np.array_equal(tau[i], m.rnea(qs[i], vs[i], as_[i])), f"rnea row {i}"
        t, r = m.frame_placement(qs[i], m.link_names[-1])
        assert np.array_equal(translation[i], t) and np.array_equal(rotation[i], r), f"row {i}"


def test_a_batch_names_its_first_bad_row():
    """Every row from 5 300 on is bad, so the threads that hold rows past it when the first
    error stops the batch meet bad rows too: the error names row 5 300, call after call."""
    s = setup_of(PACKAGE_CASES[0])
    m, rows = s.model, 20000
    qs = np.tile(s.q_ours, (rows, 1))
    zeros = np.zeros((rows, m.nv))
    qs[5300:, 1] = np.inf
    for _ in range(20):
        with pytest.raises(sd.DynamicsError, match=rf"^row 5300: q\[1\] \({m.v_names[1]}\) is inf"):
            m.rnea(qs, zeros, zeros)


def test_a_batch_runs_with_the_gil_released():
    """While one thread computes a long batch, the main thread keeps running Python: the longest
    pause between its loop's iterations during the call is a small part of the call. A held GIL
    would pause it for the whole computation (the switch interval cannot preempt native code)."""
    s = setup_of(PACKAGE_CASES[1])
    m = s.model
    rows = 20000
    qs = np.tile(s.q_ours, (rows, 1))
    zeros = np.zeros((rows, m.nv))
    window = {}

    def work():
        window["start"] = time.perf_counter()
        m.aba_derivatives(qs, zeros, zeros)
        window["end"] = time.perf_counter()

    worker = threading.Thread(target=work)
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())
    worker.join()
    start, end = window["start"], window["end"]
    assert end - start > 0.1, f"the batch took {end - start:.4f} s: too short to tell"
    inside = [start] + [t for t in ticks if start < t < end] + [end]
    longest = max(b - a for a, b in zip(inside, inside[1:]))
    assert longest < 0.5 * (end - start), (
        f"the main thread paused {longest:.3f} s during a {end - start:.3f} s batch"
    )


def test_a_batch_reads_its_inputs_as_they_were_when_called():
    """A batch computes with the GIL released, so another Python thread may write its input
    arrays meanwhile. It reads a copy taken with the GIL held: its results are those of the
    inputs as they were at the call, equal bit for bit to those of an untouched copy, while a
    thread adds 1 to the inputs' rows, from the last block back, during the call. The switch
    interval is raised until that thread runs, so it runs only once the call has released the
    GIL (after the copy: the result cannot depend on timing), and it must have started writing
    before the call returned (else the test shows nothing). Read in place, the last rows would
    be read after the thread changed them: the results differ. What this cannot show is a write
    by native code that releases the GIL (a numpy operation on a large array) during the copy."""
    s = setup_of(PACKAGE_CASES[0])
    m, rng, rows, block = s.model, np.random.default_rng(5), 200_000, 1000
    qs = np.tile(s.q_ours, (rows, 1)) + 0.1 * rng.standard_normal((rows, m.nq))
    vs, as_ = rng.standard_normal((2, rows, m.nv))
    untouched = qs.copy(), vs.copy(), as_.copy()
    want = m.rnea(*untouched)
    go, done, first_write = threading.Event(), threading.Event(), []
    interval = sys.getswitchinterval()

    def scribble():
        go.wait()
        sys.setswitchinterval(interval)  # running: the call has released the GIL
        while not done.is_set():
            for stop in range(rows, 0, -block):
                if not first_write:
                    first_write.append(time.perf_counter())
                for x in (qs, vs, as_):
                    x[stop - block : stop] += 1.0
                if done.is_set():
                    break

    writer = threading.Thread(target=scribble)
    writer.start()
    sys.setswitchinterval(100.0)
    try:
        go.set()
        got = m.rnea(qs, vs, as_)
        returned = time.perf_counter()
    finally:
        sys.setswitchinterval(interval)
        done.set()
        writer.join()
    assert first_write and first_write[0] < returned, "no write during the call: too short to tell"
    assert not np.array_equal(qs[-1], untouched[0][-1]), "the inputs were not written"
    assert np.array_equal(got, want), f"{np.sum(np.any(got != want, axis=1))} rows differ"


def stub_names():
    """(module names, Model's names) that the stubs declare, public only."""
    tree = ast.parse(STUBS.read_text())
    module, model = set(), set()
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            module.add(node.name)
            if node.name == "Model":
                model = {n.name for n in node.body if isinstance(n, ast.FunctionDef)}
        elif isinstance(node, ast.Assign):
            module.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return {n for n in module if not n.startswith("_")}, {n for n in model if not n.startswith("_")}


def test_stubs_name_exactly_the_public_api():
    module, model = stub_names()
    public = {n for n in dir(sd) if not n.startswith("_")} - {"spatial_dynamics"}
    assert module == public
    assert model == {n for n in dir(sd.Model) if not n.startswith("_")}


def stub_functions():
    """{name: (where the module keeps it, its stub)} of every function the stubs declare: at
    module level, and in classes (``Model.rnea``, dunder methods too), properties left out."""
    tree = ast.parse(STUBS.read_text())
    found = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            found[node.name] = (sd, node)
        elif isinstance(node, ast.ClassDef):
            for f in node.body:
                if isinstance(f, ast.FunctionDef) and not any(
                    isinstance(d, ast.Name) and d.id == "property" for d in f.decorator_list
                ):
                    found[f"{node.name}.{f.name}"] = (getattr(sd, node.name), f)
    return found


def stub_parameters(f: ast.FunctionDef):
    """A stub's parameters as (name, kind, default), in order; a method's ``self`` is
    positional-only, as ``$self`` in a ``__text_signature__``."""
    a, empty, kinds = f.args, inspect.Parameter.empty, inspect.Parameter
    positional = a.posonlyargs + a.args
    defaults = [ast.literal_eval(d) for d in a.defaults]
    defaults = [empty] * (len(positional) - len(defaults)) + defaults
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in f.decorator_list)
    out = []
    for i, (arg, default) in enumerate(zip(positional, defaults)):
        only = arg in a.posonlyargs or (i == 0 and arg.arg == "self" and not static)
        kind = kinds.POSITIONAL_ONLY if only else kinds.POSITIONAL_OR_KEYWORD
        out.append((arg.arg, kind, default))
    if a.vararg:
        out.append((a.vararg.arg, kinds.VAR_POSITIONAL, empty))
    for arg, default in zip(a.kwonlyargs, a.kw_defaults):
        default = empty if default is None else ast.literal_eval(default)
        out.append((arg.arg, kinds.KEYWORD_ONLY, default))
    if a.kwarg:
        out.append((a.kwarg.arg, kinds.VAR_KEYWORD, empty))
    return out


def test_stub_signatures_are_the_module_s():
    """Each function and method the stubs declare (dunder methods too) has the parameters of
    the module's ``__text_signature__``: the same names in the same order, kinds and defaults,
    so a call by keyword that type-checks against the stubs is one the module takes."""
    found = stub_functions()
    assert "Model.rnea" in found and "Model.__deepcopy__" in found
    for name, (owner, stub) in found.items():
        function = getattr(owner, stub.name)
        assert function.__text_signature__, f"{name} has no __text_signature__"
        parameters = inspect.signature(function).parameters.values()
        ours = [(p.name, p.kind, p.default) for p in parameters]
        assert ours == stub_parameters(stub), f"{name}: module {function.__text_signature__}"
    m = sd.Model.from_urdf(ARM)
    assert m.__deepcopy__(memo={}) is m


ARM = REPO / "config" / "models" / "default_arm.urdf"


def test_an_unaligned_array_is_read():
    """A C-contiguous float64 array whose data is not 8-byte aligned (np.frombuffer at an odd
    offset) is copied, not read in place: the results are those of an aligned copy."""
    s = setup_of(PACKAGE_CASES[0])
    m, q = s.model, s.q_ours
    one = np.frombuffer(bytearray(8 * m.nq + 1), dtype=np.float64, offset=1)
    two = np.frombuffer(bytearray(16 * m.nq + 1), dtype=np.float64, offset=1).reshape(2, m.nq)
    assert one.flags.c_contiguous and not one.flags.aligned
    assert two.flags.c_contiguous and not two.flags.aligned
    # frombuffer over a bytearray is writeable: the state is written into the odd offset.
    one[:] = q
    two[:] = np.stack([q, q])
    assert np.array_equal(m.gravity(one), m.gravity(q))
    assert np.array_equal(m.gravity(two), m.gravity(np.stack([q, q])))


def test_results_too_big_raise_memory_error():
    """A batch whose results cannot be allocated (a broadcast view: rows that take no memory)
    raises MemoryError naming the shape, before any argument is copied."""
    s = setup_of(PACKAGE_CASES[0])
    m = s.model
    huge = np.broadcast_to(s.q_ours, (10**12, m.nq))
    with pytest.raises(MemoryError, match=r"\(1000000000000, "):
        m.gravity(huge)
    beyond = np.broadcast_to(s.q_ours, (2**56, m.nq))  # (N, nv, nv) results: more bytes than isize holds
    too_big = rf"^a result of shape \(72057594037927936, {m.nv}, {m.nv}\) would take more bytes"
    with pytest.raises(MemoryError, match=too_big):
        m.mass_matrix(beyond)
    v = np.broadcast_to(s.v_ours, (2**56, m.nv))
    with pytest.raises(MemoryError):
        m.rnea_derivatives(beyond, v, v)


class _Refuses:
    """An array-like whose conversion raises `error`."""

    def __init__(self, error):
        self.error = error

    def __array__(self, dtype=None, copy=None):
        raise self.error


def test_shapes_are_checked_before_conversion_and_numpy_errors_propagate():
    """A wrong shape is refused from the array's shape alone (a broadcast view of 10^12 rows is
    not copied); MemoryError and KeyboardInterrupt raised while converting an argument reach
    the caller unchanged."""
    s = setup_of(PACKAGE_CASES[0])
    m = s.model
    wide = np.broadcast_to(np.zeros(m.nq + 1, dtype=np.float32), (10**12, m.nq + 1))
    with pytest.raises(sd.DynamicsError, match=rf"^q has shape \(1000000000000, {m.nq + 1}\)"):
        m.gravity(wide)
    rows = np.broadcast_to(np.zeros(m.nv, dtype=np.float32), (10**12, m.nv))
    with pytest.raises(sd.DynamicsError, match=r"v holds 1000000000000 states \(2-D\), q 2 states"):
        m.rnea(np.zeros((2, m.nq)), rows, rows)
    with pytest.raises(MemoryError, match="no memory for q"):
        m.gravity(_Refuses(MemoryError("no memory for q")))
    with pytest.raises(KeyboardInterrupt):
        m.rnea(s.q_ours, s.v_ours, _Refuses(KeyboardInterrupt()))


@pytest.mark.parametrize(
    "make, what",
    [
        (lambda n: np.zeros(n, dtype=complex), "an array of dtype complex128"),
        (lambda n: np.ones(n, dtype=bool), "an array of dtype bool"),
        (lambda n: np.zeros(n, dtype="M8[s]"), r"an array of dtype datetime64\[s\]"),
        (lambda n: np.zeros(n, dtype=object), "an array of dtype object"),
        (lambda n: ["1.5"] * n, r"list \(read by numpy as dtype <U3\)"),
        (lambda n: b"0.25", "bytes"),
        (lambda n: None, "NoneType"),
        (lambda n: {}, "dict"),
        (lambda n: object(), "object"),
        (lambda n: [1.0] * (n - 1) + [None], "list"),
    ],
    ids=[
        "complex", "bool", "datetime64", "object_array", "strings", "bytes", "None", "dict", "object",
        "list_with_None",
    ],
)
def test_only_real_numbers_are_taken(make, what):
    """Arguments are real numbers: a float, signed or unsigned integer array, or a sequence of
    them. Anything else is a TypeError naming the argument and what it was."""
    s = setup_of(PACKAGE_CASES[0])
    m = s.model
    with pytest.raises(TypeError, match=rf"^q must be real numbers .*, not {what}"):
        m.gravity(make(m.nq))
    with pytest.raises(TypeError, match=rf"^tau must be real numbers .*, not {what}"):
        m.forward_dynamics(s.q_ours, s.v_ours, make(m.nv))


def test_masked_arrays_are_refused():
    """A numpy masked array is refused, mask or not, by every array argument of every method,
    for one state and for N, with a TypeError naming the argument: the computation would read
    the values under the mask. Its ``.data`` (or ``.filled(x)``) is taken."""
    s = setup_of(PACKAGE_CASES[0])
    m, q, v, frame = s.model, s.q_ours, s.v_ours, s.model.link_names[-1]
    methods = (
        (m.rnea, ("q", "v", "a")),
        (m.gravity, ("q",)),
        (m.forward_dynamics, ("q", "v", "tau")),
        (m.mass_matrix, ("q",)),
        (lambda q: m.frame_placement(q, frame), ("q",)),
        (lambda q: m.frame_jacobian(q, frame, "local"), ("q",)),
        (m.center_of_mass, ("q",)),
        (m.rnea_derivatives, ("q", "v", "a")),
        (m.aba_derivatives, ("q", "v", "tau")),
    )
    for state in ((q, v, v), tuple(np.tile(x, (3, 1)) for x in (q, v, v))):
        for call, names in methods:
            for k, name in enumerate(names):
                args = list(state[: len(names)])
                mask = np.zeros(args[k].shape, dtype=bool)
                mask.flat[-1] = True
                args[k] = np.ma.array(args[k], mask=mask)
                refused = rf"^{name} is a masked array .* pass {name}\.filled"
                with pytest.raises(TypeError, match=refused):
                    call(*args)
    hidden = q.copy()
    hidden[0] = 1e300
    masked = np.ma.array(hidden, mask=[True] + [False] * (m.nq - 1))
    with pytest.raises(TypeError, match=r"^q is a masked array"):
        m.gravity(np.ma.array(q))  # no mask at all: refused too
    with pytest.raises(TypeError, match=r"^q is a masked array"):
        m.gravity(masked)
    assert np.array_equal(m.gravity(masked.filled(q[0])), m.gravity(q))
    assert np.array_equal(m.gravity(masked.data), m.gravity(hidden))
    # Inside a list or tuple (numpy.asarray would drop the mask): a masked row of N states, or
    # numpy.ma.masked among one state's values, named by its index.
    with pytest.raises(TypeError, match=r"^q\[1\] is a masked array .* pass q\[1\]\.filled"):
        m.gravity([q, masked, q])
    with pytest.raises(TypeError, match=r"^v\[0\] is a masked array"):
        m.rnea(q, (masked, q), [q, q])
    with pytest.raises(TypeError, match=r"^q\[2\] is a masked array"):
        m.gravity([*q[:2], np.ma.masked, *q[3:]])
    assert np.array_equal(m.gravity([q, masked.data]), np.stack([m.gravity(q), m.gravity(hidden)]))


def test_real_dtypes_are_converted():
    s = setup_of(PACKAGE_CASES[0])
    m = s.model
    q = np.arange(m.nq) - 2
    want = m.gravity(q.astype(np.float64))
    for dtype in (np.int8, np.int32, np.int64, np.float16, np.float32):
        assert np.array_equal(m.gravity(q.astype(dtype)), want), dtype
    assert np.array_equal(m.gravity(np.abs(q).astype(np.uint16)), m.gravity(np.abs(q).astype(np.float64)))
    assert np.array_equal(m.gravity(tuple(q.tolist())), want)


def test_from_urdf_file_errors_are_os_errors(tmp_path):
    """A file that cannot be read raises the OSError subclass of its cause, with the path as
    its filename; a device, a FIFO or a file over 64 MiB is refused without being read
    (DynamicsError naming the path); a URDF the library refuses names the file."""
    missing = tmp_path / "missing.urdf"
    with pytest.raises(FileNotFoundError) as raised:
        sd.Model.from_urdf(missing)
    assert raised.value.filename == str(missing)
    with pytest.raises(IsADirectoryError) as raised:
        sd.Model.from_urdf(str(tmp_path))
    assert raised.value.filename == str(tmp_path)
    if os.geteuid() != 0:  # root reads any file
        locked = tmp_path / "locked.urdf"
        locked.write_text(ARM.read_text())
        locked.chmod(0)
        with pytest.raises(PermissionError):
            sd.Model.from_urdf(locked)
    with pytest.raises(sd.DynamicsError, match="^/dev/zero is not a regular file"):
        sd.Model.from_urdf("/dev/zero")
    fifo = tmp_path / "fifo.urdf"
    os.mkfifo(fifo)
    with pytest.raises(sd.DynamicsError, match="is not a regular file"):
        sd.Model.from_urdf(fifo)
    big = tmp_path / "big.urdf"
    with open(big, "wb") as f:
        f.truncate((64 << 20) + 1)  # sparse: no disk, and not read
    with pytest.raises(sd.DynamicsError, match=r"big.urdf is larger than 64 MiB"):
        sd.Model.from_urdf(big)
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='r'><link name='a'>")
    with pytest.raises(sd.DynamicsError, match=rf"^{bad}: cannot parse the URDF"):
        sd.Model.from_urdf(bad)


def test_a_model_pickles_and_copies():
    """A model pickles (its URDF text and options, not its path) into one that gives the same
    bits; copy.copy and copy.deepcopy give the model itself (it is immutable)."""
    m = sd.Model.from_urdf(ARM, floating_base=True, ignore_mimic=True)
    back = pickle.loads(pickle.dumps(m))
    assert isinstance(back, sd.Model) and back is not m
    assert (back.nq, back.nv, back.v_names, back.link_names) == (m.nq, m.nv, m.v_names, m.link_names)
    assert back.forward_dynamics_method == m.forward_dynamics_method
    rng = np.random.default_rng(3)
    q = rng.standard_normal((4, m.nq))
    q[:, 3:7] /= np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    v, a = rng.standard_normal((2, 4, m.nv))
    assert np.array_equal(back.rnea(q, v, a), m.rnea(q, v, a))
    assert np.array_equal(back.mass_matrix(q[0]), m.mass_matrix(q[0]))
    fixed = pickle.loads(pickle.dumps(sd.Model.from_urdf(ARM)))
    assert fixed.nv == m.nv - 6
    assert copy.copy(m) is m and copy.deepcopy(m) is m
    assert copy.deepcopy([m, m])[0] is m


def test_center_of_mass_is_of_the_moving_bodies():
    """The mass of center_of_mass leaves out links welded to the world, as Pinocchio's
    computeTotalMass: default_arm's base counts only on a floating base. The docstring says
    so."""
    fixed, floating = sd.Model.from_urdf(ARM), sd.Model.from_urdf(ARM, floating_base=True)
    q = np.zeros(floating.nq)
    q[6] = 1.0
    fixed_mass, floating_mass = fixed.center_of_mass(np.zeros(fixed.nq))[0], floating.center_of_mass(q)[0]
    assert fixed_mass < floating_mass
    reference = pin.buildModelFromUrdf(str(ARM))
    assert abs(fixed_mass - pin.computeTotalMass(reference)) <= 1e-12 * floating_mass
    doc = sd.Model.center_of_mass.__doc__
    assert "total mass" not in doc and "moving bodies" in doc and "welded to the world" in doc
