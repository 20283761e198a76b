#!/usr/bin/env bash
# Demo: the handout's lamp jumps. Both hinges extend hard for 0.1 s, then go limp; the foot
# touches the ground (z = 0) at its four corners through penalty contacts. Writes lamp.csv
# (time, positions, velocities, energy) and prints the highest base height and the deepest
# penetration. Usage: launch_scripts/sim_lamp.sh [OUTPUT.csv]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-lamp.csv}"
cargo build --release --locked --quiet --manifest-path "$repo/Cargo.toml"
"$repo/target/release/spatial_dynamics" simulate --scene lamp --integrator semi_implicit_euler \
    --dt 0.0002 --duration 1.5 --initial '{"hinge1": 0.6, "hinge2": -1.4}' \
    --effort '{"hinge1": -1.0, "hinge2": 3.0}' --effort-until 0.1 --output "$out"
awk -F, 'NR > 1 && $3 > max { max = $3; t = $1 } END { printf "highest base z: %.3f m at t = %.3f s (rows in %s)\n", max, t, FILENAME }' "$out"
