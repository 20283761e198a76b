#!/usr/bin/env bash
# Simulation steps per second, ours against MuJoCo (C, mj_step), on the same URDFs, integrators
# (RK4 and semi-implicit Euler) and step (1 ms): UR5 and Solo12 on a floating base, gravity on,
# zero commands, no contact, limits or damping, from a displaced and moving initial state; both
# timed inside their own process over runs of STEPS steps with no output (median of REPEATS),
# alternately in ROUNDS rounds (the ratio: the median of the rounds' own ratios).
# Prints a markdown table: steps per second of each, ours / MuJoCo (> 1: we are faster), the
# same from each side's fastest round, and the difference of the end states (after STEPS × 1 ms = 1 s by default). Fails when a joint's
# angle or velocity differs from MuJoCo's by more than 1e-9 (see benches/mujoco/compare.py for
# what is compared and why a floating base's pose is reported, not asserted).
#
# Usage: launch_scripts/bench_mujoco.sh
#   Environment: STEPS (1000), REPEATS (7), ROUNDS (5: ours then MuJoCo, alternately), DT (0.001),
#   TOLERANCE (1e-9); SKIP_BUILD=1 uses our binary as it is; PYTHON picks python3.11.
#
# What it does, idempotently:
#   1. target/mujoco-venv: a venv (git-ignored) with MuJoCo from PyPI (its C library and
#      headers ship in the wheel), numpy, and the robots (example-robot-data, without its
#      dependencies). Reinstalled only when the package list below changes.
#   2. target/bench-mujoco/steps from benches/mujoco/steps.c, gcc -O3 -march=native against the
#      wheel's libmujoco, rebuilt when the source or the flags change.
#   3. cargo build --release, then benches/mujoco/compare.py: per robot it writes the URDF as
#      MuJoCo should read it (target/bench-mujoco/NAME.urdf) and runs both benches.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$repo/target/mujoco-venv"
build="$repo/target/bench-mujoco"
python="${PYTHON:-python3.11}"
packages=(mujoco==4.0.0 numpy --no-deps example-robot-data==6.0.0)

log() { printf '== %s\n' "$*" >&2; }
die() { printf 'bench_mujoco.sh: %s\n' "$*" >&2; exit 1; }

# --- 1. the venv ---------------------------------------------------------------------------------
# example-robot-data's dependencies are Pinocchio's: only its robot files are needed here.
source "$repo/launch_scripts/bench_venv.sh"
bench_venv "$venv" "$python" "${packages[@]}"
site="$(echo "$venv"/lib/python3*/site-packages)"
mujoco_dir="$site/mujoco"
[[ -f "$mujoco_dir/include/mujoco/mujoco.h" ]] || die "no MuJoCo headers under $mujoco_dir"
libraries=("$mujoco_dir"/libmujoco.so.*)
[[ -f "${libraries[0]}" ]] || die "no libmujoco.so.* under $mujoco_dir"
library="$(basename "${libraries[0]}")"
robots="$site/cmeel.prefix/share/example-robot-data/robots"
[[ -d "$robots" ]] || die "no example-robot-data robots under $robots"

# --- 2. the MuJoCo bench -------------------------------------------------------------------------
src="$repo/benches/mujoco/steps.c"
cc_flags=(-O3 -march=native -Wall -I"$mujoco_dir/include")
ld_flags=(-L"$mujoco_dir" -l:"$library" -Wl,-rpath,"$mujoco_dir")
flags_stamp="$build/.flags"
if [[ ! -x "$build/steps" || "$src" -nt "$build/steps" \
      || "$(cat "$flags_stamp" 2>/dev/null)" != "${cc_flags[*]} ${ld_flags[*]}" ]]; then
    log "compiling $src"
    mkdir -p "$build"
    gcc "${cc_flags[@]}" "$src" -o "$build/steps" "${ld_flags[@]}"
    echo "${cc_flags[*]} ${ld_flags[*]}" > "$flags_stamp"
fi

# --- 3. ours, then the runs ----------------------------------------------------------------------
ours="$repo/target/release/spatial_dynamics"
if [[ "${SKIP_BUILD:-0}" != 1 ]]; then
    log "cargo build --release"
    (cd "$repo" && cargo build --release --quiet)
fi
[[ -x "$ours" ]] || die "no $ours (cargo build --release)"

"$venv/bin/python" "$repo/benches/mujoco/compare.py" --ours "$ours" --mujoco-steps "$build/steps" \
    --robots "$robots" --work "$build" --steps "${STEPS:-1000}" --repeats "${REPEATS:-7}" \
    --rounds "${ROUNDS:-5}" --dt "${DT:-0.001}" --tolerance "${TOLERANCE:-1e-9}"
