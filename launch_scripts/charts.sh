#!/usr/bin/env bash
# Regenerates the README's charts into docs/charts/ (SVG + the CSV behind each):
#   timing.svg          ns per call of every `bench` kernel against nv: pendulum chains of 1…256
#                       links and the example-robot-data robots, ours and Pinocchio's (same run,
#                       same URDF files), with O(n), O(n²), O(n³) slopes;
#   accuracy.svg        forward-dynamics error against time per call, planar chains swept over
#                       length and mass ratio, against a double-double reference;
#   work_precision.svg  integrators: error at T = 1 s against CPU time per simulated second.
#
# Usage: launch_scripts/charts.sh
#   Environment: OUT (docs/charts) is the output directory; NO_PINOCCHIO=1 skips Pinocchio and the
#   robots (then nothing is downloaded or compiled but our binary); SKIP_BUILD=1 uses
#   target/release/spatial_dynamics as it is.
#
# What it does: launch_scripts/bench_pinocchio.sh --build-only (its venv with Pinocchio and
# example-robot-data, and the Pinocchio bench: minutes the first time, then nothing), cargo build
# --release, then `spatial_dynamics chart --out OUT --pinocchio-bench BIN --robot NAME=URDF[,floating]…`
# (about 5 minutes on 2 cores). Timings are of one thread on whatever machine this runs on: a busy
# machine makes them noisy.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${OUT:-$repo/docs/charts}"
chart_args=()
if [[ "${NO_PINOCCHIO:-0}" != 1 ]]; then
    built="$("$repo/launch_scripts/bench_pinocchio.sh" --build-only)"
    while IFS= read -r line; do
        case "$line" in
            bench=*) chart_args+=(--pinocchio-bench "${line#bench=}") ;;
            robot=*) chart_args+=(--robot "${line#robot=}") ;;
        esac
    done <<< "$built"
fi
if [[ "${SKIP_BUILD:-0}" != 1 ]]; then
    (cd "$repo" && cargo build --release --quiet)
fi
"$repo/target/release/spatial_dynamics" chart --out "$out" "${chart_args[@]}"
