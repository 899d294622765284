#!/usr/bin/env bash
# Run the test suite in the local environment (created on first use, with the extra [test]);
# any pytest arguments pass through (-n 2: on two cores with pytest-xdist, which the extra
# brings; about half the time, but a signal test can time out there under load).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" test
cd "$(dirname "${BASH_SOURCE[0]}")/.."
exec python -m pytest "$@"
