"""The C ABI (src/c) from C and C++ programs, against Pinocchio.

Compiles src/c/tests/programs/probe.c (gcc, C11) and probe.cpp (g++ -std=c++20, through the C++
header spatial_dynamics.hpp) against include/spatial_dynamics.h, each once linked with the
shared library and once with the static one (``-lpthread -ldl -lm``), both found beside the
binary ``SPATIAL_DYNAMICS_BIN`` points at (target/release/; ``cargo build --release`` makes
them). Each program reads a random state and prints τ = RNEA(q, q̇, q̈), g(q), q̈ = FD(q, q̇, τ),
M(q), an end-effector link's Jacobian in the three reference frames and the derivatives
(sd_rnea_derivatives: ∂τ/∂q, ∂τ/∂q̇, M; sd_aba_derivatives: ∂q̈/∂q, ∂q̈/∂q̇, M⁻¹, against
computeRNEADerivatives / computeABADerivatives, whose M and M⁻¹ may hold only their upper
triangle and are symmetrised); on UR5 and Panda (the
example-robot-data URDFs of test_pinocchio_reference.py, mimic tags ignored as Pinocchio's
model does) every one must match Pinocchio's to 1e-9 relative to the quantity's largest entry
(coordinates matched by name). Bad input from C and C++ (a NaN in q, an unknown frame, a
description that does not parse, and from C++ a span of the wrong length) must give the status
code and a message naming what is wrong. Panda with its finger mimic followed is checked against
Pinocchio's model constrained by the mimic map (test_pinocchio_reference.ProjectedMimicRef).

Then builds src/c/examples (gravity_compensation.cpp) with CMake through
``find_package(spatial_dynamics_c)`` and src/c/cmake, runs it for one second on UR5, and checks
the g(q) it prints at its last q against Pinocchio.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_pinocchio_reference import (  # noqa: E402  (the sibling reference test's tools)
    REPO,
    ProjectedMimicRef,
    binary_path,
    build_pin_model,
    robots_dir,
)

C_DIR = REPO / "src" / "c"
PROGRAMS = C_DIR / "tests" / "programs"
TOLERANCE = 1e-9

# (name, URDF under example-robot-data's robots/, the link whose Jacobian is checked: fused
# into its body by fixed joints in both robots).
ROBOTS = (
    ("ur5", "ur_description/urdf/ur5_robot.urdf", "ee_link"),
    ("panda", "panda_description/urdf/panda.urdf", "panda_hand"),
)
LANGUAGES = ("c", "c++")
LINKS = ("shared", "static")
REFERENCES = {
    "J_world": pin.ReferenceFrame.WORLD,
    "J_local": pin.ReferenceFrame.LOCAL,
    "J_aligned": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
}


def library_dir() -> Path:
    directory = binary_path().parent
    for name in ("libspatial_dynamics_c.so", "libspatial_dynamics_c.a"):
        if not (directory / name).is_file():
            pytest.fail(f"{directory / name} is missing: build it with `cargo build --release`")
    return directory


def compile_probe(language: str, link: str, out_dir: Path) -> Path:
    lib = library_dir()
    out = out_dir / f"probe_{language.replace('+', 'p')}_{link}"
    if language == "c":
        command = ["gcc", "-std=c11", str(PROGRAMS / "probe.c")]
    else:
        command = ["g++", "-std=c++20", str(PROGRAMS / "probe.cpp")]
    command += ["-Wall", "-Wextra", "-pedantic", "-Werror", "-O2", f"-I{C_DIR / 'include'}", "-o", str(out)]
    if link == "shared":
        command += [f"-L{lib}", "-lspatial_dynamics_c", f"-Wl,-rpath,{lib}"]
    else:
        command += [str(lib / "libspatial_dynamics_c.a"), "-lpthread", "-ldl", "-lm"]
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, f"{' '.join(command)}\n{done.stderr}"
    return out


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    out_dir = tmp_path_factory.mktemp("c_abi")
    return {(lang, link): compile_probe(lang, link, out_dir) for lang in LANGUAGES for link in LINKS}


def test_static_probes_do_not_load_the_shared_library(probes):
    for lang in LANGUAGES:
        needed = subprocess.run(["ldd", str(probes[lang, "static"])], capture_output=True, text=True).stdout
        assert "spatial_dynamics" not in needed, needed
        needed = subprocess.run(["ldd", str(probes[lang, "shared"])], capture_output=True, text=True).stdout
        assert "libspatial_dynamics_c.so" in needed, needed


def run_probe(probe: Path, urdf: Path, frame: str, values: np.ndarray, ignore_mimic: bool = True) -> dict:
    stdin = " ".join(repr(float(x)) for x in values)
    command = [str(probe), str(urdf), "1" if ignore_mimic else "0", frame]
    done = subprocess.run(command, input=stdin, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = {}
    for line in done.stdout.splitlines():
        head, _, rest = line.partition(" ")
        if head == "error":
            what, status, message = rest.split(" ", 2)
            lines[f"error {what}"] = (int(status), message)
        else:
            lines[head] = rest.split()
    return lines


def close(ours, ref, what):
    ours, ref = np.asarray(ours, dtype=float), np.asarray(ref, dtype=float)
    scale = max(1.0, float(np.max(np.abs(ref))))
    err = float(np.max(np.abs(ours - ref))) / scale
    assert err <= TOLERANCE, f"{what}: relative difference {err:.3e} > {TOLERANCE:g}\nours {ours}\nref  {ref}"


def symmetric(upper: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose upper triangle is ``upper``'s."""
    return np.triu(upper) + np.triu(upper, 1).T


def check_derivatives(ours, model, data, q, v, a, tau, pin_index, label):
    """The probe's six derivative matrices (row-major, our coordinate order) against Pinocchio's."""
    nv = model.nv
    order = np.ix_(pin_index, pin_index)
    dtau_dq, dtau_dv, mass = (np.array(m, copy=True) for m in pin.computeRNEADerivatives(model, data, q, v, a))
    ddq_dq, ddq_dv, minv = (np.array(m, copy=True) for m in pin.computeABADerivatives(model, data, q, v, tau))
    expected = {
        "dtau_dq": dtau_dq,
        "dtau_dv": dtau_dv,
        "M_rnea": symmetric(mass),
        "ddq_dq": ddq_dq,
        "ddq_dv": ddq_dv,
        "Minv": symmetric(minv),
    }
    for key, ref in expected.items():
        close(np.array(ours[key], dtype=float).reshape(nv, nv), ref[order], f"{label} {key}")


@pytest.mark.parametrize("robot,relative,frame", ROBOTS, ids=[r[0] for r in ROBOTS])
@pytest.mark.parametrize("language", LANGUAGES)
@pytest.mark.parametrize("link", LINKS)
def test_matches_pinocchio(probes, robot, relative, frame, language, link):
    urdf = robots_dir() / relative
    model = build_pin_model(urdf, floating=False)
    data = model.createData()
    assert model.nq == model.nv, f"{robot}: the test maps q by velocity index"
    rng = np.random.default_rng(28 + len(robot))
    nv = model.nv
    q = rng.uniform(-1.0, 1.0, nv)
    v, a, tau = (rng.standard_normal(nv) for _ in range(3))
    # Our coordinates by name in Pinocchio's order: pin_index[i] is our coordinate i there.
    probe = probes[language, link]
    names = run_probe(probe, urdf, frame, np.zeros(4 * nv))["names"]
    index = {model.names[j]: model.joints[j].idx_v for j in range(1, model.njoints)}
    pin_index = np.array([index[n] for n in names])
    assert sorted(pin_index) == list(range(nv)), names
    ours = run_probe(probe, urdf, frame, np.concatenate([x[pin_index] for x in (q, v, a, tau)]))
    values = {k: np.array(ours[k], dtype=float) for k in ("tau", "g", "qdd", "M", *REFERENCES)}
    label = f"{robot} {language} {link}"
    close(values["tau"], pin.rnea(model, data, q, v, a)[pin_index], f"{label} tau")
    close(values["g"], pin.computeGeneralizedGravity(model, data, q)[pin_index], f"{label} g")
    close(values["qdd"], pin.aba(model, data, q, v, tau)[pin_index], f"{label} qdd")
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    close(values["M"].reshape(nv, nv), mass[np.ix_(pin_index, pin_index)], f"{label} M")
    frame_id = model.getFrameId(frame)
    assert frame_id < model.nframes, f"{robot}: Pinocchio has no frame {frame}"
    for key, reference in REFERENCES.items():
        ref = pin.computeFrameJacobian(model, data, q, frame_id, reference)[:, pin_index]
        close(values[key].reshape(6, nv), ref, f"{label} {key}")
    check_derivatives(ours, model, data, q, v, a, tau, pin_index, label)
    # Bad input: the status code (1: SD_ERROR_INPUT, 2: SD_ERROR_USAGE) and the message.
    last = names[-1]
    status, message = ours["error nan"]
    assert status == 1 and f"({last}) is NaN, not a finite number" in message, message
    status, message = ours["error frame"]
    assert status == 1 and "no link named 'no_such_link'" in message and frame in message, message
    status, message = ours["error urdf"]
    assert status in (-1, 1) and "cannot parse the URDF" in message, message
    if language == "c++":
        status, message = ours["error length"]
        assert status == 2 and f"q has {nv - 1} values, the model needs {nv}" in message, message


@pytest.mark.parametrize("language", LANGUAGES)
def test_mimic_joints_follow_their_leader(probes, language):
    """Panda with its finger mimic followed (the default): the forward-dynamics method chosen for
    the model handles it (aba does not), and every answer is Pinocchio's mimic-ignored model
    constrained by the mimic map."""
    urdf = robots_dir() / ROBOTS[1][1]
    ref = ProjectedMimicRef(urdf, floating=False)
    nv = ref.nv
    assert ref.nq == nv and ref.mimic_rows, "panda: one mimic joint, no floating base"
    probe = probes[language, "shared"]
    names = run_probe(probe, urdf, "panda_hand", np.zeros(4 * nv), ignore_mimic=False)["names"]
    index = {j.name: j.idx_v for j in ref.joints}
    pin_index = np.array([index[n] for n in names])
    assert sorted(pin_index) == list(range(nv)), names
    rng = np.random.default_rng(2828)
    q = rng.uniform(-1.0, 1.0, nv)
    v, a, tau = (rng.standard_normal(nv) for _ in range(3))
    stdin = np.concatenate([x[pin_index] for x in (q, v, a, tau)])
    ours = run_probe(probe, urdf, "panda_hand", stdin, ignore_mimic=False)
    values = {k: np.array(ours[k], dtype=float) for k in ("tau", "g", "qdd", "M")}
    close(values["tau"], ref.rnea(q, v, a)[pin_index], f"panda mimic {language} tau")
    close(values["g"], ref.gravity(q)[pin_index], f"panda mimic {language} g")
    close(values["qdd"], ref.forward_dynamics(q, v, tau)[pin_index], f"panda mimic {language} qdd")
    mass = ref.mass_matrix(q)[np.ix_(pin_index, pin_index)]
    close(values["M"].reshape(nv, nv), mass, f"panda mimic {language} M")


def cmake() -> str:
    for candidate in (Path(sys.executable).parent / "cmake", REPO / ".venv" / "bin" / "cmake"):
        if candidate.is_file():
            return str(candidate)
    found = shutil.which("cmake")
    if not found:
        pytest.fail("cmake not found (pip install cmake into the venv)")
    return found


def test_example_builds_with_cmake_and_runs(tmp_path):
    lib = library_dir()
    build = tmp_path / "build"
    env = dict(os.environ, SPATIAL_DYNAMICS_C_LIBRARY_DIR=str(lib))
    for command in (
        [cmake(), "-S", str(C_DIR / "examples"), "-B", str(build), f"-Dspatial_dynamics_c_DIR={C_DIR / 'cmake'}"],
        [cmake(), "--build", str(build)],
    ):
        done = subprocess.run(command, capture_output=True, text=True, env=env)
        assert done.returncode == 0, f"{' '.join(command)}\n{done.stdout}\n{done.stderr}"
    urdf = robots_dir() / ROBOTS[0][1]
    done = subprocess.run([str(build / "gravity_compensation"), str(urdf), "1"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("1000 calls of g(q) at 1 kHz on 6 coordinates: per call min"), lines[0]
    print(lines[0])
    # g at the example's last q (q_i = 0.5 sin(0.5 t + 0.3 i), t = 0.999 s), against Pinocchio.
    printed = dict(line[2:].split("] = ") for line in lines[1:])
    model = build_pin_model(urdf, floating=False)
    names = list(printed)
    q_ours = np.array([0.5 * math.sin(0.5 * 0.999 + 0.3 * i) for i in range(len(names))])
    index = {model.names[j]: model.joints[j].idx_v for j in range(1, model.njoints)}
    q = np.zeros(model.nq)
    q[[index[n] for n in names]] = q_ours
    g = pin.computeGeneralizedGravity(model, model.createData(), q)
    for n in names:
        assert math.isclose(float(printed[n]), g[index[n]], rel_tol=1e-7, abs_tol=1e-7), (n, printed[n], g[index[n]])
