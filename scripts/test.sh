#!/usr/bin/env bash
# Run the test suite in the local environment (created on first use, with the extra [test]),
# on both cores (pytest-xdist, one worker per core, the tests of a file in one worker);
# any pytest arguments pass through (-n 0 runs it in one process).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" test
cd "$(dirname "${BASH_SOURCE[0]}")/.."
exec python -m pytest -n 2 --dist loadfile "$@"
