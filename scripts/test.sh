#!/usr/bin/env bash
# Run the test suite in the local environment (created on first use, with the extra [test]).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" test
cd "$(dirname "${BASH_SOURCE[0]}")/.."
exec python -m pytest "$@"
