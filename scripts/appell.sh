#!/usr/bin/env bash
# Run the appell command line in the local environment (created on first use, runtime dependencies only).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" runtime
exec appell "$@"
