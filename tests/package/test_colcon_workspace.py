"""The repository as a ROS 2 package: built by colcon in a fresh workspace, installed where
`ros2 run` and `ros2 launch` look, and the installed node serving.

What a user does (README, "In a ROS 2 workspace"), with colcon from PyPI and cargo-ament-build
from crates.io: the repository's committed files (``git archive HEAD``) are cloned into
``WS/src/spatial_dynamics``, then ``colcon build --base-paths src src/spatial_dynamics/msg
--cargo-args --release`` in WS. The checks:

* colcon finds exactly ``spatial_dynamics`` (ament_cargo) and ``spatial_dynamics_msgs``
  (ament_cmake), and nothing in any other directory holding a Cargo.toml or package.xml (src/core,
  src/vendor/*, tests/fuzz) even when pointed at it;
* both packages are in the ament index, the node's executable ``spatial_dynamics_node`` is in
  ``lib/spatial_dynamics/`` (found as ``ros2 run`` finds it: ament_index_python with the
  AMENT_PREFIX_PATH that ``install/setup.bash`` sets), the launch file and config/ in share/;
* the installed executable, started with no arguments as ``ros2 run`` would, serves the embedded
  default arm: an inverse-dynamics call agrees with Pinocchio on config/models/default_arm.urdf;
* the launch file (loaded with stand-ins for ``launch`` / ``launch_ros``, which have no wheels)
  names that package and executable, the installed params file, and only parameters the running
  node declares (its ``list_parameters`` service); with ``urdf:=`` it adds robot_state_publisher
  with the file's text, and the node started with the launch file's arguments serves that URDF.

Cost: the build reuses the registry dependencies compiled in the repository's target/release
(copied into colcon's build dir; cargo's hashes do not depend on where the workspace is), and
compiles the repository's own crates (the archive's files are new, so cargo rebuilds them).
``SD_COLCON_COLD=1`` builds from nothing instead.

Needs: colcon in this Python environment (launch_scripts/setup_python_env.sh installs it),
``cargo ament-build`` (``cargo install cargo-ament-build --locked``), git, and a private network
namespace: ``launch_scripts/netns_exec.sh .venv/bin/python -m pytest -q tests/package``.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "dds"))
import sd_dds_support as sd  # noqa: E402
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics  # noqa: E402

REPO = sd.REPO
VENV_BIN = Path(sys.executable).parent
DOMAIN_ID = int(os.environ.get("SD_TEST_DOMAIN_ID") or os.getpid() % 100 + 101)
PACKAGES = {"spatial_dynamics": "ament_cargo", "spatial_dynamics_msgs": "ros.ament_cmake"}


def setup_module():
    interfaces = sorted(name for _, name in socket.if_nameindex())
    if interfaces != ["lo"]:
        pytest.exit(
            f"run inside a private network namespace (this one has {interfaces}): "
            "launch_scripts/netns_exec.sh .venv/bin/python -m pytest tests/package",
            returncode=4,
        )
    os.environ["ROS_DOMAIN_ID"] = str(DOMAIN_ID)


def run(cmd, cwd, env=None, log=None, timeout=1800):
    """Runs a command; on failure the assertion shows its output (or the log's tail)."""
    out = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         stdin=subprocess.DEVNULL, timeout=timeout, text=True)
    if log is not None:
        Path(log).write_text(out.stdout)
    assert out.returncode == 0, f"{' '.join(map(str, cmd))} failed ({out.returncode}):\n{out.stdout[-6000:]}"
    return out.stdout


def colcon_env():
    """The environment of a user's build shell: the venv's colcon, cmake and ROS packages found
    first (what sourcing a ROS installation's setup.bash does), cargo offline (every crate is in
    the local registry cache already; this namespace has no network)."""
    env = dict(os.environ)
    venv = str(VENV_BIN.parent)
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    env["AMENT_PREFIX_PATH"] = venv
    env["CMAKE_PREFIX_PATH"] = venv
    env["CARGO_NET_OFFLINE"] = "true"
    env.pop("CARGO_TARGET_DIR", None)
    return env


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A colcon workspace holding this repository's committed files, built."""
    for tool in ("git", "cargo"):
        assert shutil.which(tool), f"{tool} is needed"
    assert (VENV_BIN / "colcon").is_file(), "colcon is not installed in this venv (launch_scripts/setup_python_env.sh)"
    probe = subprocess.run(["cargo", "ament-build", "--help"], capture_output=True)
    assert probe.returncode == 0, "cargo-ament-build is missing: cargo install cargo-ament-build --locked"

    ws = tmp_path_factory.mktemp("colcon_ws")
    src = ws / "src" / "spatial_dynamics"
    src.mkdir(parents=True)
    # The committed files, as a clone has them; -m: fresh mtimes, so cargo compiles our crates.
    archive = subprocess.run(["git", "-C", str(REPO), "archive", "--format=tar", "HEAD"], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-m", "-f", "-"], cwd=src, input=archive, check=True)

    seeded = REPO / "target" / "release"
    if os.environ.get("SD_COLCON_COLD") != "1" and seeded.is_dir():
        (ws / "build" / "spatial_dynamics").mkdir(parents=True)
        t0 = time.monotonic()
        subprocess.run(["cp", "-a", "--reflink=auto", str(seeded), str(ws / "build" / "spatial_dynamics")], check=True)
        print(f"seeded colcon's target dir from {seeded} in {time.monotonic() - t0:.1f} s")

    t0 = time.monotonic()
    run([VENV_BIN / "colcon", "build", "--base-paths", "src", "src/spatial_dynamics/msg", "--cargo-args", "--release"],
        cwd=ws, env=colcon_env(), log=ws / "colcon_build.log")
    print(f"colcon build: {time.monotonic() - t0:.0f} s (log {ws / 'colcon_build.log'})")
    return ws


def colcon_list(ws, *base_paths):
    out = run([VENV_BIN / "colcon", "list", "--base-paths", *base_paths], cwd=ws, env=colcon_env())
    found = {}
    for line in out.splitlines():
        parts = line.split("\t")
        if len(parts) == 3:
            found[parts[0]] = parts[2].strip("()")
    assert "ERROR" not in out, out
    return found


def test_colcon_finds_exactly_the_two_packages(workspace):
    assert colcon_list(workspace, "src", "src/spatial_dynamics/msg") == PACKAGES
    # Pointed at every other directory of the clone that holds a manifest (the library crate,
    # vendored crates, the fuzz crate), colcon finds nothing.
    clone = workspace / "src" / "spatial_dynamics"
    manifests = {p.parent for name in ("Cargo.toml", "package.xml") for p in clone.rglob(name)}
    inner = sorted(str(d.relative_to(workspace)) for d in manifests - {clone, clone / "msg"})
    assert "src/spatial_dynamics/src/core" in inner
    assert colcon_list(workspace, *inner, "src/spatial_dynamics/src", "src/spatial_dynamics/tests") == {}


def installed_env(ws):
    """The environment after `source install/setup.bash` (what `ros2 run` sees)."""
    out = run(["bash", "-c", "source install/setup.bash && env -0"], cwd=ws)
    return dict(item.split("=", 1) for item in out.split("\0") if "=" in item)


def ros2_run_path(ws, package, executable):
    """Where `ros2 run PACKAGE EXECUTABLE` finds the executable: PREFIX/lib/PACKAGE/EXECUTABLE,
    PREFIX from the ament index on the sourced AMENT_PREFIX_PATH."""
    code = ("import sys; from ament_index_python.packages import get_package_prefix; "
            "print(get_package_prefix(sys.argv[1]))")
    prefix = run([sys.executable, "-c", code, package], cwd=ws, env=installed_env(ws)).strip()
    return Path(prefix) / "lib" / package / executable


def test_install_layout_and_ament_index(workspace):
    install = workspace / "install"
    for package in PACKAGES:
        marker = install / package / "share" / "ament_index" / "resource_index" / "packages" / package
        assert marker.is_file(), f"{package} is not in the ament index"
        assert (install / package / "share" / package / "package.xml").is_file()
    share = install / "spatial_dynamics" / "share" / "spatial_dynamics"
    for rel in ("launch/spatial_dynamics.launch.py", "config/default.yaml", "config/models/default_arm.urdf"):
        assert (share / rel).is_file(), f"share/spatial_dynamics/{rel} is not installed"
    exe = ros2_run_path(workspace, "spatial_dynamics", "spatial_dynamics_node")
    assert exe == install / "spatial_dynamics" / "lib" / "spatial_dynamics" / "spatial_dynamics_node"
    assert exe.is_file() and os.access(exe, os.X_OK)


@pytest.fixture(scope="module")
def ros():
    session = sd.RosSession(DOMAIN_ID, "colcon_package_test")
    yield session
    session.close()


def start(ws, ros, args, tmp_path, label, prefix="/spatial_dynamics"):
    exe = ros2_run_path(ws, "spatial_dynamics", "spatial_dynamics_node")
    env = installed_env(ws)
    env["ROS_DOMAIN_ID"] = str(DOMAIN_ID)
    before = ros.rosout_writers()
    node = sd.NodeProcess(exe, args, env, tmp_path / f"{label}.log", label, subcommand=())
    try:
        if not ros.wait_new_node(before):
            raise AssertionError(f"the installed node was not discovered within {sd.EVENT_S} s:\n{node.describe()}")
        ros.wait_for_service(DescribeModel, f"{prefix}/describe_model")
    except BaseException:
        node.stop()
        raise
    return node


def inverse_dynamics_matches_pinocchio(ros, urdf, prefix="/spatial_dynamics"):
    ref = sd.PinRef(urdf)
    names = ref.names
    q = [0.1 * (i + 1) * (-1) ** i for i in range(len(names))]
    v = [0.3 - 0.1 * i for i in range(len(names))]
    a = [0.2 * i - 0.5 for i in range(len(names))]
    resp = ros.call(InverseDynamics, f"{prefix}/inverse_dynamics",
                    InverseDynamics.Request(name=names, position=q, velocity=v, acceleration=a))
    assert resp.success, resp.message
    want = ref.pick(ref.rnea(ref.q(names, q), ref.v(names, v), ref.v(names, a)), names)
    sd.assert_close(resp.effort, want, f"inverse dynamics of {Path(urdf).name}")


def test_installed_node_serves_the_default_arm(workspace, ros, tmp_path):
    node = start(workspace, ros, [], tmp_path, "installed")
    try:
        inverse_dynamics_matches_pinocchio(ros, sd.DEFAULT_ARM_URDF)
    finally:
        node.stop()


# ---- the launch file --------------------------------------------------------------------------
#
# No launch / launch_ros wheels exist: the launch file is loaded with stand-ins that record what
# it asks for. OpaqueFunction is evaluated with a context whose launch configurations are the
# declared defaults overridden by the arguments given, as `ros2 launch ... NAME:=VALUE` does.


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context.launch_configurations[self.name]


def load_launch_file(path, share_dirs):
    stubs = {
        "launch": types.ModuleType("launch"),
        "launch.actions": types.ModuleType("launch.actions"),
        "launch.substitutions": types.ModuleType("launch.substitutions"),
        "launch_ros": types.ModuleType("launch_ros"),
        "launch_ros.actions": types.ModuleType("launch_ros.actions"),
        "ament_index_python": types.ModuleType("ament_index_python"),
        "ament_index_python.packages": types.ModuleType("ament_index_python.packages"),
    }
    stubs["launch"].LaunchDescription = lambda entities: list(entities)
    stubs["launch.actions"].DeclareLaunchArgument = type("DeclareLaunchArgument", (_Recorded,), {})
    stubs["launch.actions"].OpaqueFunction = type("OpaqueFunction", (_Recorded,), {})
    stubs["launch.substitutions"].LaunchConfiguration = _LaunchConfiguration
    stubs["launch_ros.actions"].Node = type("Node", (_Recorded,), {})
    stubs["ament_index_python.packages"].get_package_share_directory = lambda pkg: str(share_dirs[pkg])
    saved = {name: sys.modules.get(name) for name in stubs}
    sys.modules.update(stubs)
    try:
        spec = importlib.util.spec_from_file_location("sd_launch_file", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.generate_launch_description()
    finally:
        for name, old in saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old


def launch_nodes(description, **arguments):
    """The Node actions the description yields for `ros2 launch ... NAME:=VALUE ...`."""
    declared = {e.args[0]: e.kwargs.get("default_value") for e in description if type(e).__name__ == "DeclareLaunchArgument"}
    unknown = set(arguments) - set(declared)
    assert not unknown, f"launch arguments not declared: {unknown}"
    context = types.SimpleNamespace(launch_configurations={**declared, **arguments})
    nodes = []
    for e in description:
        if type(e).__name__ == "OpaqueFunction":
            nodes.extend(e.kwargs["function"](context))
        elif type(e).__name__ == "Node":
            nodes.append(e)
    return nodes


def node_ros_args(node, tmp_path):
    """The arguments launch_ros gives the executable: the name and namespace remaps, each params
    file as --params-file, and each dict written to a params file of its own under `/**`."""
    args = ["--ros-args"]
    if node.kwargs.get("name"):
        args += ["-r", f"__node:={node.kwargs['name']}"]
    if node.kwargs.get("namespace"):
        args += ["-r", f"__ns:=/{node.kwargs['namespace'].strip('/')}"]
    for i, p in enumerate(node.kwargs.get("parameters", [])):
        if isinstance(p, dict):
            path = tmp_path / f"launch_params_{i}.yaml"
            path.write_text(yaml.safe_dump({"/**": {"ros__parameters": p}}))
            p = path
        args += ["--params-file", str(p)]
    return args


def parameter_names(node):
    """Every parameter a launch Node sets: dict keys, and the params files' entries for it."""
    names = set()
    for p in node.kwargs.get("parameters", []):
        if isinstance(p, dict):
            names |= set(p)
            continue
        doc = yaml.safe_load(Path(p).read_text())
        for key, body in doc.items():
            if key in ("/**", node.kwargs.get("name")) or key.endswith("/" + str(node.kwargs.get("name"))):
                names |= set(body["ros__parameters"])
    return names


@pytest.fixture(scope="module")
def installed_launch(workspace):
    share = workspace / "install" / "spatial_dynamics" / "share" / "spatial_dynamics"
    return share, load_launch_file(share / "launch" / "spatial_dynamics.launch.py", {"spatial_dynamics": share})


def test_launch_file_is_plain_python_with_the_launch_entry_point():
    path = REPO / "launch_scripts" / "launch" / "spatial_dynamics.launch.py"
    tree = ast.parse(path.read_text(), filename=str(path))
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in functions


def test_launch_file_starts_the_installed_node_with_declared_parameters(workspace, installed_launch, ros, tmp_path):
    share, description = installed_launch
    (node,) = launch_nodes(description)
    assert node.kwargs["package"] == "spatial_dynamics"
    exe = ros2_run_path(workspace, node.kwargs["package"], node.kwargs["executable"])
    assert exe.is_file(), f"the launch file's executable is not installed: {exe}"
    assert node.kwargs["parameters"] == [str(share / "config" / "default.yaml")]

    running = start(workspace, ros, node_ros_args(node, tmp_path), tmp_path, "launched")
    try:
        declared = set(ros.list_parameters())
        assert "method" in declared and "robot_description" in declared, declared
        given = parameter_names(node)
        assert given, "the default params file sets nothing for the node"
        assert given <= declared, f"parameters the node does not declare: {sorted(given - declared)}"
        inverse_dynamics_matches_pinocchio(ros, sd.DEFAULT_ARM_URDF)
    finally:
        running.stop()


def test_launch_file_with_urdf_adds_robot_state_publisher(workspace, installed_launch, ros, tmp_path):
    share, description = installed_launch
    urdf = sd.PARTICLE_URDF
    text = urdf.read_text()
    ours, rsp = launch_nodes(description, urdf=str(urdf), namespace="particle")
    assert (rsp.kwargs["package"], rsp.kwargs["executable"]) == ("robot_state_publisher", "robot_state_publisher")
    assert rsp.kwargs["parameters"] == [{"robot_description": text}]
    assert rsp.kwargs["namespace"] == ours.kwargs["namespace"] == "particle"
    assert ours.kwargs["parameters"][-1] == {"robot_description": text}

    running = start(workspace, ros, node_ros_args(ours, tmp_path), tmp_path, "launched_urdf", prefix="/particle/spatial_dynamics")
    try:
        declared = set(ros.list_parameters(node="/particle/spatial_dynamics"))
        assert parameter_names(ours) <= declared
        inverse_dynamics_matches_pinocchio(ros, urdf, prefix="/particle/spatial_dynamics")
    finally:
        running.stop()
