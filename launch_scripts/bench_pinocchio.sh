#!/usr/bin/env bash
# Times our algorithms against Pinocchio (C++) on the same URDFs in the same run (dynamics,
# frame_jacobian / center_of_mass against computeFrameJacobian / jacobianCenterOfMass, and
# rnea_derivatives / aba_derivatives against computeRNEADerivatives / computeABADerivatives), and prints a
# markdown table: per robot and algorithm, our ns per call, Pinocchio's, and Pinocchio / ours
# (> 1: we are faster).
#
# Usage: launch_scripts/bench_pinocchio.sh [--build-only]
#   --build-only: steps 1 and 2 only (no cargo build, no timing), then print what they made, one
#   KEY=VALUE a line: `bench=PATH` (the Pinocchio bench) and, per robot of the table below,
#   `robot=NAME=URDF[,floating]` (its first URDF that exists; the form `spatial_dynamics chart
#   --robot` takes). launch_scripts/charts.sh uses it.
#   Environment: STATES (1024), REPEATS (7), MIN_TIME (0.2 s per repeat) go to both benches;
#   ROUNDS (1) times each robot that many times, ours then Pinocchio back to back, and reports
#   per cell the median over rounds of each round's ratio (on a shared VM whose speed drifts by
#   tens of percent over minutes, a ratio of two runs taken seconds apart is what holds) and,
#   with more than one round, each library's fastest round against the other's (a VM whose
#   speed switches between levels can put ours and Pinocchio at different levels in one round);
#   MARCH (native) is g++'s -march for the Pinocchio bench; OURS_NATIVE=1 also builds ours with
#   -C target-cpu=native (into target/bench-native, so the shared target/release is untouched);
#   SKIP_BUILD=1 uses our binary as it is, OURS_BIN=PATH another binary (implies SKIP_BUILD);
#   PYTHON picks python3.11.
#
# What it does, idempotently:
#   1. target/bench-venv: a venv (git-ignored) with Pinocchio's C++ headers and libraries (PyPI
#      `pin`), Eigen and urdfdom headers (cmeel-eigen, cmeel-urdfdom-headers) and the robots
#      (example-robot-data). Reinstalled only when the package list below changes.
#   2. target/bench-pinocchio/bench from benches/pinocchio/bench.cpp, g++ -O3 -march=native
#      -DNDEBUG, Pinocchio's algorithms compiled from its headers (no template instantiation
#      from the shared library), rebuilt when the source or the flags change (about 4 minutes).
#   3. cargo build --release, then for each robot `spatial_dynamics bench --json --ignore-mimic`
#      (Pinocchio's URDF parser treats mimic joints as independent) and the Pinocchio bench.
# Note: by default our binary is built for the baseline x86-64 target while the Pinocchio bench
# gets -march=native: the comparison is against Pinocchio at its best.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$repo/target/bench-venv"
build="$repo/target/bench-pinocchio"
python="${PYTHON:-python3.11}"
packages=(pin==4.1.0 example-robot-data==6.0.0 cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0)
bench_args=(--states "${STATES:-1024}" --repeats "${REPEATS:-7}" --min-time "${MIN_TIME:-0.2}")

build_only=0
case "${1:-}" in
    --build-only) build_only=1 ;;
    "") ;;
    *) printf 'usage: %s [--build-only]\n' "$0" >&2; exit 2 ;;
esac

# The robots: NAME FLOATING(0|1) URDF [FALLBACK_URDF], paths under example-robot-data's robots/.
robot_table=(
    "UR5 0 ur_description/urdf/ur5_robot.urdf"
    "Panda 0 panda_description/urdf/panda.urdf"
    "Baxter 0 baxter_description/urdf/baxter.urdf"
    "TALOS 1 talos_data/robots/talos_full_v2.urdf talos_data/robots/talos_reduced.urdf"
    "Solo12 1 solo_description/robots/solo12.urdf"
    "ANYmal 1 anymal_b_simple_description/robots/anymal.urdf"
)

log() { printf '== %s\n' "$*" >&2; }
die() { printf 'bench_pinocchio.sh: %s\n' "$*" >&2; exit 1; }

# --- 1. the venv ---------------------------------------------------------------------------------
source "$repo/launch_scripts/bench_venv.sh"
bench_venv "$venv" "$python" "${packages[@]}"
prefix="$(echo "$venv"/lib/python3*/site-packages/cmeel.prefix)"
[[ -d "$prefix/include/pinocchio" ]] || die "no Pinocchio headers under $prefix"
robots="$prefix/share/example-robot-data/robots"

# --- 2. the Pinocchio bench ----------------------------------------------------------------------
src="$repo/benches/pinocchio/bench.cpp"
# The URDF parser lives in libpinocchio_parsers.so, built for baseline x86-64, and hands us a
# Model: with AVX Eigen would align (and free) its memory differently from the library, so keep
# the library's 16-byte alignment and plain malloc (the vector instructions stay).
cxx_flags=(-std=c++17 -O3 -march="${MARCH:-native}" -DNDEBUG
    -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1
    -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3
    -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0
    -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30
    -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12
    -I"$prefix/include" -I"$prefix/include/eigen3" -I"$prefix/include/urdfdom_headers"
    -I"$prefix/include/urdfdom")
ld_flags=(-L"$prefix/lib" -Wl,-rpath,"$prefix/lib"
    -lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lboost_filesystem -lboost_serialization)
flags_stamp="$build/.flags"
if [[ ! -x "$build/bench" || "$src" -nt "$build/bench" \
      || "$(cat "$flags_stamp" 2>/dev/null)" != "${cxx_flags[*]} ${ld_flags[*]}" ]]; then
    log "compiling $src (about 4 minutes)"
    mkdir -p "$build"
    g++ "${cxx_flags[@]}" "$src" -o "$build/bench" "${ld_flags[@]}" > "$build/compile.log" 2>&1 \
        || { tail -40 "$build/compile.log" >&2; die "g++ failed (see $build/compile.log)"; }
    echo "${cxx_flags[*]} ${ld_flags[*]}" > "$flags_stamp"
fi

if [[ "$build_only" == 1 ]]; then
    echo "bench=$build/bench"
    for row in "${robot_table[@]}"; do
        read -r name floating urdf fallback <<< "$row"
        [[ -f "$robots/$urdf" || -z "$fallback" ]] || urdf="$fallback"
        echo "robot=$name=$robots/$urdf$([[ $floating == 1 ]] && echo ,floating)"
    done
    exit 0
fi

# --- 3. ours, then the runs ----------------------------------------------------------------------
ours="$repo/target/release/spatial_dynamics"
cargo_env=()
if [[ "${OURS_NATIVE:-0}" == 1 ]]; then
    ours="$repo/target/bench-native/release/spatial_dynamics"
    cargo_env=(CARGO_TARGET_DIR="$repo/target/bench-native" RUSTFLAGS="-C target-cpu=native")
fi
if [[ -n "${OURS_BIN:-}" ]]; then
    ours="$OURS_BIN"
elif [[ "${SKIP_BUILD:-0}" != 1 ]]; then
    log "cargo build --release ${cargo_env[*]}"
    (cd "$repo" && env "${cargo_env[@]}" cargo build --release --quiet)
fi
[[ -x "$ours" ]] || die "no $ours (cargo build --release)"

results="$build/results.jsonl"
: > "$results"
run_robot() {  # NAME FLOATING(0|1) URDF [FALLBACK_URDF]
    local name="$1" floating="$2" urdf="$robots/$3" fallback="${4:-}"
    local extra=()
    [[ "$floating" == 1 ]] && extra=(--floating-base)
    local ours_json pin_json frame
    # Pinocchio times frame_jacobian on the link ours did (its JSON's "frame").
    if ! ours_json="$("$ours" bench --urdf "$urdf" --ignore-mimic "${extra[@]}" --json "${bench_args[@]}")" \
        || ! frame="$(printf '%s' "$ours_json" | "$venv/bin/python" -c 'import json, sys; print(json.load(sys.stdin)["frame"])')" \
        || ! pin_json="$("$build/bench" "$urdf" "${extra[@]}" --frame "$frame" "${bench_args[@]}")"; then
        if [[ -n "$fallback" ]]; then
            log "$name: $3 failed; trying $fallback"
            run_robot "$name" "$floating" "$fallback"
            return
        fi
        die "$name: a bench failed on $urdf"
    fi
    printf '{"robot": "%s", "urdf": "%s", "floating": %s, "round": %s, "ours": %s, "pinocchio": %s}\n' \
        "$name" "$(basename "$urdf")" "$([[ $floating == 1 ]] && echo true || echo false)" \
        "$round" "$ours_json" "$pin_json" >> "$results"
    log "$name done (round $round)"
}

rounds="${ROUNDS:-1}"
log "timing (${bench_args[*]}), $rounds round(s): about 15 s per robot, library and round"
for row in "${robot_table[@]}"; do
    for round in $(seq "$rounds"); do
        # shellcheck disable=SC2086 # the row splits into run_robot's arguments
        run_robot $row
    done
done

"$venv/bin/python" - "$results" <<'EOF'
import json, statistics, sys

runs = [json.loads(line) for line in open(sys.argv[1])]
kernels = ["rnea", "crba", "fd_aba", "fd_crba", "fd_rnea_columns", "gravity", "frame_jacobian",
           "center_of_mass", "rnea_derivatives", "aba_derivatives"]

# One row per robot: per kernel the median time of each library over the rounds and the median
# of the rounds' ratios (each round times ours and Pinocchio back to back).
rows = []
for r in runs:
    if not rows or rows[-1]["robot"] != r["robot"]:
        rows.append(dict(r, rounds=[]))
    rows[-1]["rounds"].append(r)

def median_of(row, f):
    values = [f(r) for r in row["rounds"]]
    return None if None in values else statistics.median(values)

def ns_of(row, lib, k):
    return median_of(row, lambda r: r[lib]["ns_per_call"][k])

def ratio_of(row, k):
    return median_of(row, lambda r: None if r["ours"]["ns_per_call"][k] is None
                     or r["pinocchio"]["ns_per_call"][k] is None
                     else r["pinocchio"]["ns_per_call"][k] / r["ours"]["ns_per_call"][k])

def fastest_ratio_of(row, k):
    # Each library's fastest round against the other's: on a VM whose speed switches between
    # levels minutes apart, a round can see ours at one level and Pinocchio at another.
    times = [[r[lib]["ns_per_call"][k] for r in row["rounds"]] for lib in ("pinocchio", "ours")]
    return None if None in times[0] + times[1] else min(times[0]) / min(times[1])

def ns(x):
    return "n/a" if x is None else f"{x:,.0f}"

def ratio(x):
    return "—" if x is None else f"{x:.2f}"

print("| robot | nv | algorithm | ours (ns) | Pinocchio (ns) | Pinocchio / ours |")
print("|---|---:|---|---:|---:|---:|")
for r in rows:
    nv = r["ours"]["nv"]
    if r["pinocchio"]["nv"] != nv:
        nv = f'{nv} (Pinocchio: {r["pinocchio"]["nv"]})'
    name = r["robot"] + (" (floating)" if r["floating"] else "")
    for k in kernels:
        o, p = ns_of(r, "ours", k), ns_of(r, "pinocchio", k)
        print(f"| {name} | {nv} | {k} | {ns(o)} | {ns(p)} | {ratio(ratio_of(r, k))} |")

def ratio_table(title, ratio_in):
    print()
    print(title)
    print()
    print("| robot | nv | " + " | ".join(kernels) + " |")
    print("|---|---:|" + "---:|" * len(kernels))
    for r in rows:
        cells = [ratio(ratio_in(r, k)) for k in kernels]
        print(f'| {r["robot"]} ({r["urdf"]}) | {r["ours"]["nv"]} | ' + " | ".join(cells) + " |")

ratio_table(f"Pinocchio / ours (> 1: we are faster; median over "
            f"{len(rows[0]['rounds']) if rows else 0} round(s) of the ratio within each round):",
            ratio_of)
if rows and len(rows[0]["rounds"]) > 1:
    ratio_table("Pinocchio's fastest round / ours (the same rounds, each library's least time):",
                fastest_ratio_of)
d = rows[0]["pinocchio"]["detail"]["pinocchio"] if rows else "?"
print()
print(f"Pinocchio {d}; crba, fd_aba and fd_crba: the faster of its LOCAL and WORLD conventions "
      f"(both in {sys.argv[1]}); frame_jacobian: the WORLD Jacobian of the link our bench names "
      f"(per robot: {', '.join(r['robot'] + ' ' + r['ours']['frame'] for r in rows)}).")
EOF
