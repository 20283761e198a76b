#!/usr/bin/env bash
# Benchmarks `spatial_dynamics replay`: joint states per second on one core and on all cores,
# over a synthetic bag of the embedded 7-DOF default arm (benches/make_replay_bag.py: 1 kHz
# JointState with positions, velocities and efforts, effort commands at 100 Hz, the URDF on
# /robot_description), writing all four outputs (gravity_effort, acceleration,
# measured_dynamics, effort_residual) with zstd chunks. Not a test: it prints a markdown table.
#
# Usage: launch_scripts/bench_replay.sh
#   Environment: MESSAGES (1000000) joint states; STORAGE (mcap) or sqlite3; ZSTD_IN (1): the
#   input MCAP has zstd chunks; ZSTD_MODE (none) file or message: rosbag2's zstd compression of
#   the input (whole storage files, or each message; implies ZSTD_IN=0); COMPRESSION (zstd) of the output; ZSTD_LEVEL (replay's default)
#   of the output; REPEATS (3, the best is kept);
#   SKIP_BUILD=1 uses target/release/spatial_dynamics as it is; BIN=PATH measures another
#   binary (e.g. an older build, for a before/after comparison); KEEP=1 keeps the bags in
#   target/bench-replay/. "1 core" pins the whole process (reader, worker, writer threads) to
#   CPU 0 with taskset and runs --jobs 1; "all cores" runs with the default --jobs (every core).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"
messages="${MESSAGES:-1000000}"
storage="${STORAGE:-mcap}"
zstd_mode="${ZSTD_MODE:-}"
zstd_in="${ZSTD_IN:-1}"
[[ -n "$zstd_mode" ]] && zstd_in=0
compression="${COMPRESSION:-zstd}"
level_flags=()
[[ -n "${ZSTD_LEVEL:-}" ]] && level_flags=(--zstd-level="$ZSTD_LEVEL")
repeats="${REPEATS:-3}"
work="$repo/target/bench-replay"
bin="${BIN:-$repo/target/release/spatial_dynamics}"

log() { printf '== %s\n' "$*" >&2; }

"$repo/launch_scripts/setup_python_env.sh" >/dev/null
if [[ "${SKIP_BUILD:-0}" != 1 ]]; then
    log "cargo build --release"
    cargo build --release --quiet
fi
command -v taskset >/dev/null || { echo "bench_replay.sh: taskset (util-linux) is needed" >&2; exit 1; }

mkdir -p "$work"
chunks=""
if [[ "$storage" == mcap && "$zstd_in" == 1 ]]; then chunks=_zstd; fi
bag="$work/bag_${storage}_${messages}${chunks}${zstd_mode:+_zstd_$zstd_mode}"
if [[ ! -f "$bag/metadata.yaml" ]]; then
    log "writing $bag"
    flags=()
    [[ "$storage" == mcap && "$zstd_in" == 1 ]] && flags+=(--zstd)
    [[ -n "$zstd_mode" ]] && flags+=(--zstd-mode "$zstd_mode")
    "$repo/.venv/bin/python" "$repo/benches/make_replay_bag.py" --out "$bag" --messages "$messages" \
        --storage "$storage" "${flags[@]}" >&2
fi

# Best of $repeats runs: joint states per wall-clock second and per CPU second (user + system
# time of every thread of the process: on a machine shared with other work, the per-core cost).
# Into the variables named by $1 and $2; a failed run (replay or its JSON) fails the script.
run() {
    local -n rate="$1" rate_cpu="$2"
    shift 2
    local best="0 0" out
    rm -f "$work/out.mcap"
    for _ in $(seq "$repeats"); do
        if ! out="$("$@" --bag "$bag" --out "$work/out.mcap" --compression "$compression" "${level_flags[@]}" --json 2>>"$work/replay.log" \
            | "$repo/.venv/bin/python" -c 'import json,sys; s=json.load(sys.stdin); print(round(s["joint_states_per_second"]), round(s["joint_states_per_cpu_second"]))' 2>>"$work/replay.log")"; then
            echo "bench_replay.sh: the run failed: $* (its messages are in $work/replay.log)" >&2
            exit 1
        fi
        if (( ${out% *} > ${best% *} )); then best="$out"; fi
    done
    read -r rate rate_cpu <<<"$best"
}

cores="$(nproc)"
log "1 core (taskset -c 0, --jobs 1), best of $repeats"
run one one_cpu taskset -c 0 "$bin" replay --jobs 1
log "all $cores cores (--jobs $cores), best of $repeats"
run all all_cpu "$bin" replay --jobs "$cores"
size_in="$(du -sh "$bag" | cut -f1)"
size_out="$(du -sh "$work/out.mcap" | cut -f1)"

echo
echo "| run | joint states/s (wall clock) | joint states per CPU second |"
echo "|---|---:|---:|"
echo "| 1 core, --jobs 1 | $one | $one_cpu |"
echo "| $cores cores, --jobs $cores | $all | $all_cpu |"
echo
echo "input: $messages joint states, $storage${chunks:+ (zstd chunks)}${zstd_mode:+ (zstd $zstd_mode mode)}, $size_in; output ($compression${ZSTD_LEVEL:+ level $ZSTD_LEVEL}): $size_out, 4 messages per joint state"
echo "load average while measuring: $(cut -d' ' -f1-3 /proc/loadavg) (other work on the machine lowers the wall-clock rates, less the CPU-second ones)"
if [[ "${KEEP:-0}" != 1 ]]; then rm -f "$work/out.mcap"; fi
