#!/usr/bin/env bash
# Run the test suite in the local environment (created on first use, with the extra [test]):
# the formatter and the linter (ruff), the type checker (mypy), then every module but the few
# that time signals, child processes and alarms, on two workers (pytest-xdist, which the extra
# brings; one module per worker at a time), then those on their own (tests/conftest.py:
# SERIAL), so that the other worker's load cannot stretch their timing (scripts/passes.sh).
# Any pytest arguments pass through to both passes; a pass that the arguments leave empty is
# skipped. APPELL_TEST_WORKERS=1 runs the first pass in one process. All test processes share
# one derivation and compiled-code cache, a temporary folder removed at the end
# ($APPELL_CACHE_DIR when set: .ci/run shares it with the matrix).
# --quick (first argument): the everyday subset, about 2.5 minutes (tests/conftest.py: HEAVY).
set -euo pipefail
if [ "${1:-}" = "--quick" ]; then
    shift
    export APPELL_QUICK=1
fi
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" test
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/passes.sh
# one derivation and compiled-code cache for both passes (scripts/passes.sh: shared_cache)
cache="$(mktemp -d "${TMPDIR:-/tmp}/appell-test-cache.XXXXXX")"
trap 'rm -rf "$cache"' EXIT
shared_cache "$cache"
# the formatter, the linter and the type checker first (pyproject.toml, [tool.ruff] and [tool.mypy]):
# a finding fails the run before the tests start
python -m ruff format --check --quiet .
python -m ruff check --quiet .
python -m mypy
status=0
run_passes "" "$@" || status=$?
[ "$status" = 5 ] && status=0  # no test selected in either pass
exit "$status"
