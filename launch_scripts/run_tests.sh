#!/usr/bin/env bash
# Runs the whole test suite: the Rust tests (unit, behaviour, command line), then the Python
# tests that check us against independent references (Pinocchio) with the release binary.
# Usage: launch_scripts/run_tests.sh        (from anywhere; sets up .venv on first use)
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

if ! command -v cargo >/dev/null 2>&1; then
    echo "cargo is needed: install Rust with rustup (https://rustup.rs) and run this again" >&2
    exit 1
fi

echo "== Rust: build and test (release) =="
cargo build --release --locked
cargo test --release --locked

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
