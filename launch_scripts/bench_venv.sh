# Sourced by the benchmark scripts (bench_pinocchio.sh, bench_mujoco.sh): a git-ignored venv
# under target/ holding exactly a list of PyPI packages, made again only when the list changes.
#
#   bench_venv VENV PYTHON PACKAGE... [--no-deps PACKAGE...]
#
# installs the packages before `--no-deps` with their dependencies and those after it without
# (a package needed only for its files). PYTHON falls back to python3 when it is not on PATH.
# The list is kept in VENV/.bench_packages.

export PIP_NO_INPUT=1 PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_PROGRESS_BAR=off

bench_venv() {
    local venv="$1" python="$2"
    shift 2
    local with=() without=() into=with arg
    for arg in "$@"; do
        if [[ "$arg" == --no-deps ]]; then into=without; continue; fi
        if [[ "$into" == with ]]; then with+=("$arg"); else without+=("$arg"); fi
    done
    local stamp="$venv/.bench_packages"
    if [[ -x "$venv/bin/python" && "$(cat "$stamp" 2>/dev/null)" == "$*" ]]; then
        return 0
    fi
    command -v "$python" >/dev/null 2>&1 || python=python3
    printf '== creating %s (%s)\n' "$venv" "$*" >&2
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet "${with[@]}"
    if ((${#without[@]})); then
        "$venv/bin/pip" install --quiet --no-deps "${without[@]}"
    fi
    echo "$*" > "$stamp"
}
