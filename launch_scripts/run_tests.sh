#!/usr/bin/env bash
# Runs the whole test suite: the Rust tests (unit, behaviour, command line), fuzzing, the Python
# tests that check us against independent references (Pinocchio) with the release binary, the
# node over DDS (and a subset of that on the genuine ROS 2 Jazzy wheels), and the repository built as a ROS 2 package by colcon.
# Usage: launch_scripts/run_tests.sh        (from anywhere; sets up .venv on first use)
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

if ! command -v cargo >/dev/null 2>&1; then
    echo "cargo is needed: install Rust with rustup (https://rustup.rs) and run this again" >&2
    exit 1
fi

# What the tests need from Debian besides Python (the C++ tests need g++, the FLOP counts
# valgrind): installed when missing and run as root, else named.
"$repo/launch_scripts/setup_python_env.sh" --debian
# Tools a test would otherwise skip itself without are required in this run.
export SD_FULL_SUITE=1

echo "== Rust: build and test (release) =="
cargo build --release --locked
cargo test --release --locked

echo "== Fuzz: each target ${SD_FUZZ_SECONDS:-60} s (cargo-fuzz on stable Rust, no sanitizer) =="
# SD_FUZZ_SECONDS=0 skips this step. With `-s none` (no sanitizer) cargo-fuzz passes only stable
# rustc flags (SanitizerCoverage through -Cpasses/-Cllvm-args): no nightly toolchain needed.
if [[ "${SD_FUZZ_SECONDS:-60}" != "0" ]]; then
    if ! cargo fuzz --version >/dev/null 2>&1; then
        cargo install cargo-fuzz --locked
    fi
    fuzz_corpus="$(mktemp -d)"
    trap 'rm -rf "$fuzz_corpus"' EXIT
    for target in urdf_model eval_request node_engine bag_readers; do
        mkdir -p "$fuzz_corpus/$target"
        cp tests/fuzz/corpus/"$target"/* "$fuzz_corpus/$target/"
    done
    cp config/models/*.urdf src/core/tests/models/*.urdf "$fuzz_corpus/urdf_model/"
    cargo fuzz build --fuzz-dir tests/fuzz -s none
    for target in urdf_model eval_request node_engine bag_readers; do
        if ! cargo fuzz run --fuzz-dir tests/fuzz -s none "$target" "$fuzz_corpus/$target" -- \
            -max_total_time="${SD_FUZZ_SECONDS:-60}" -timeout=20 -rss_limit_mb=4096 -print_final_stats=1 \
            >"$fuzz_corpus/$target.log" 2>&1; then
            tail -n 60 "$fuzz_corpus/$target.log" >&2
            echo "fuzz target $target failed; the input is in tests/fuzz/artifacts/$target/ (replay:" \
                "cargo fuzz run --fuzz-dir tests/fuzz -s none $target FILE)" >&2
            exit 1
        fi
        grep -E "^Done [0-9]+ runs" "$fuzz_corpus/$target.log" | sed "s/^/$target: /"
    done
fi

echo "== Python: reference tests (Pinocchio) =="
"$repo/launch_scripts/setup_python_env.sh"
export SPATIAL_DYNAMICS_BIN="$repo/target/release/spatial_dynamics"
"$repo/.venv/bin/python" -m pytest -q "$repo/tests/python"

echo "== DDS: the node against rclpy, in a private network namespace (loopback only) =="
if ! command -v ip >/dev/null 2>&1; then
    if [[ "$(id -u)" -eq 0 ]] && command -v apt-get >/dev/null 2>&1; then
        apt-get update -qq </dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iproute2 </dev/null
    else
        echo "the DDS tests need 'ip' (Debian package iproute2) and 'unshare' (util-linux)" >&2
        exit 1
    fi
fi
"$repo/launch_scripts/netns_exec.sh" "$repo/.venv/bin/python" -m pytest -q "$repo/tests/dds"

echo "== DDS on genuine Jazzy wheels (rclpy 7.1, Fast DDS 2.14) =="
# The wheels above are Kilted-era; this runs a subset of tests/dds against the \`ros-jazzy-*\`
# wheels in .venv-jazzy (msg/ built there too), one file per interface of the node:
jazzy_dds_tests=(
    test_topics.py          # every input and output topic, with stamps; diagnostics
    test_services_arm.py    # inverse_dynamics, forward_dynamics, mass_matrix, describe_model
    test_parameters.py      # the parameter services: list, get, set, describe, types; their effect
    test_model_sources.py   # robot_description: parameter, params file, urdf_file, latched topic, reload
    test_simulate_mode.py   # simulate mode: joint_states, /clock, ~/reset, ~/pause, ~/step
)
"$repo/launch_scripts/setup_python_env.sh" --jazzy
# A Python started below another venv's Python would inherit its bootstrapper's guard and ROS
# library path: this one must set up its own.
jazzy_python=(env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE -u LD_LIBRARY_PATH "$repo/.venv-jazzy/bin/python")
jazzy_paths=()
for test in "${jazzy_dds_tests[@]}"; do jazzy_paths+=("$repo/tests/dds/$test"); done
"$repo/launch_scripts/netns_exec.sh" "${jazzy_python[@]}" -m pytest -q "${jazzy_paths[@]}"

echo "== ROS package: colcon builds the repository in a fresh workspace; the installed node and launch file =="
# colcon comes with .venv; colcon-ros-cargo runs `cargo ament-build` (crates.io), installed once.
if ! cargo ament-build --help >/dev/null 2>&1; then
    cargo install cargo-ament-build --locked
fi
"$repo/launch_scripts/netns_exec.sh" "$repo/.venv/bin/python" -m pytest -q "$repo/tests/package"
