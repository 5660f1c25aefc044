#!/usr/bin/env bash
# The tests on three Python versions, run from the repository root (CI: .ci/run):
#   1. the default interpreter (`python`, where `pip install -e ".[dev]"` installed the checkout):
#      the full suite, `python -m pytest -q -n 2` (pytest-xdist: two worker processes, each test file
#      on one of them, $DFRMOT_TEST_WORKERS to change the number);
#   2. Python 3.12 and 3.13, each where pyenv has it (`pyenv prefix 3.12`, else the newest
#      $PYENV_ROOT/versions/3.12.N; absent: one line saying it is skipped): a venv of its own,
#      created once and reused, in ${DFRMOT_VENVS:-$HOME/.cache/dfrmot_jax/venvs}/py3.12 (outside
#      the checkout), the checkout installed into it (`pip install -q -e ".[dev]"`), then
#      `dfrmot demo` into a temporary folder and the fast tier, `pytest -m "not slow" -n 2`.
# Every step runs even after another failed; one summary line per interpreter at the end, and the
# exit status is 1 when any step failed (pytest's 5, no test collected, is a failure here too).
set -euo pipefail
cd "$(dirname "$0")/.."

VENVS="${DFRMOT_VENVS:-$HOME/.cache/dfrmot_jax/venvs}"
PYENV_ROOT="${PYENV_ROOT:-$HOME/.pyenv}"
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
summary=()
failed=0
# the tests in worker processes, one test file per worker at a time (module fixtures built once)
XDIST="-n ${DFRMOT_TEST_WORKERS:-2} --dist loadfile"

# run NAME CMD...: runs one step, its time and outcome appended to $steps; returns CMD's status
run() {
    local name=$1 start=$SECONDS status=0
    shift
    echo "== $label: $name: $*"
    "$@" || status=$?
    if [ "$status" -eq 0 ]; then
        steps+="$name ok $((SECONDS - start)) s; "
    else
        [ "$status" -eq 5 ] && echo "$label: $name: pytest collected no test (exit 5)" >&2
        steps+="$name FAILED (exit $status) $((SECONDS - start)) s; "
        failed=1
    fi
    return "$status"
}

# find_python 3.12: the path of pyenv's python3.12, or nothing
find_python() {
    local prefix=""
    if command -v pyenv >/dev/null 2>&1; then
        prefix="$(pyenv prefix "$1" 2>/dev/null || true)"
    fi
    if [ -z "$prefix" ]; then
        prefix="$(printf '%s\n' "$PYENV_ROOT"/versions/"$1".* | grep -E "/$1\.[0-9]+$" | sort -V | tail -n 1 || true)"
    fi
    if [ -n "$prefix" ] && [ -x "$prefix/bin/python" ]; then
        echo "$prefix/bin/python"
    fi
}

# 1. the default interpreter: the full suite
label="python $(python -c 'import platform; print(platform.python_version())')"
steps=""
run "full suite" python -m pytest -q $XDIST || true
summary+=("$label (default): ${steps%; }")

# 2. Python 3.12 and 3.13: install, demo, fast tier
for version in 3.12 3.13; do
    label="python $version"
    py="$(find_python "$version")"
    if [ -z "$py" ]; then
        summary+=("$label: skipped: not installed (neither \`pyenv prefix $version\` nor $PYENV_ROOT/versions/$version.N)")
        echo "${summary[-1]}"
        continue
    fi
    label="python $("$py" -c 'import platform; print(platform.python_version())')"
    venv="$VENVS/py$version"
    steps=""
    # made once (with a current pip, whose resolver installs [dev] faster than the bundled one);
    # again when its interpreter no longer runs (pyenv's version removed)
    if ! "$venv/bin/python" -c "" 2>/dev/null; then
        run "venv" "$py" -m venv --clear --upgrade-deps "$venv" || { summary+=("$label: ${steps%; }"); continue; }
    fi
    if run "install" "$venv/bin/python" -m pip install -q -e ".[dev]"; then
        run "demo" "$venv/bin/dfrmot" demo --out "$TMP/demo$version" || true
        run "fast tier" "$venv/bin/python" -m pytest -q -m "not slow" -p no:cacheprovider $XDIST || true
    fi
    summary+=("$label ($venv): ${steps%; }")
done

echo
echo "== summary"
printf '%s\n' "${summary[@]}"
exit "$failed"
