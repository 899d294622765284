#!/usr/bin/env bash
# Sourced by scripts/test.sh and scripts/test-matrix.sh (not run on its own).
#
# run_passes JUNIT PYTEST-ARGS...: the suite's two passes (tests/conftest.py: SERIAL),
# every selected module but the serial ones on $APPELL_TEST_WORKERS (default 2) pytest-xdist
# workers, one module per worker at a time, then the serial ones in one process, so that
# the other worker's load cannot stretch their timing of signals, child processes and alarms.
# JUNIT: '' or a path prefix; each pass then writes its JUnit report to JUNIT-parallel.xml and
# JUNIT-serial.xml. Returns the first failing pass's exit status, 5 when neither pass selected
# a test (pytest's "no tests collected"), else 0; a pass that selects nothing is not a failure.
run_passes() {
    local junit="$1" workers="${APPELL_TEST_WORKERS:-2}" part rc empty=0 status=0
    shift
    # the modules in the order of tests/conftest.py (LONGEST_FIRST), not by their number of tests
    local parallel=(-n "$workers" --dist loadfile --no-loadscope-reorder)
    [ "$workers" = 1 ] && parallel=()
    for part in parallel serial; do
        local args=()
        [ "$part" = parallel ] && args=("${parallel[@]}")
        [ -n "$junit" ] && args+=("--junitxml=$junit-$part.xml")
        rc=0
        APPELL_TEST_PART="$part" python -m pytest "${args[@]}" "$@" || rc=$?
        if [ "$rc" = 5 ]; then
            empty=$((empty + 1))
        elif [ "$rc" != 0 ] && [ "$status" = 0 ]; then
            status="$rc"
        fi
    done
    [ "$status" = 0 ] && [ "$empty" = 2 ] && status=5
    return "$status"
}

# shared_cache DIR: unless the caller chose one, $APPELL_CACHE_DIR is DIR (created), so that
# every test process of the run, both passes and their child processes share one derivation
# and compiled-code cache (each bundled example derived and compiled once per run, not once
# per process) that starts empty and never touches the user's ~/.cache/appell. The caller
# removes DIR at its end. The tests of the caches themselves use their own folders.
shared_cache() {
    if [ -z "${APPELL_CACHE_DIR:-}" ]; then
        mkdir -p "$1"
        export APPELL_CACHE_DIR="$1"
    fi
}
