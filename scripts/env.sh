#!/usr/bin/env bash
# Create (or refresh) the local environment .venv with appell.
# Usage: source scripts/env.sh runtime   appell and its runtime dependencies only (the main command)
#        source scripts/env.sh test      also the test and docs tools, the extra [test] (the test command)
# Re-installs only when pyproject.toml changed or the test tools are wanted and missing.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.appell-installed"
mode="runtime"
if [ "${1:-}" = "test" ]; then
    mode="test"
fi
want="$(sha256sum "$root/pyproject.toml" | cut -d' ' -f1)"
have=""
if [ -f "$stamp" ]; then
    have="$(cat "$stamp")"
fi
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
# an environment with the test tools serves the main command too
if [ "$have" != "$want test" ] && { [ "$mode" = "test" ] || [ "$have" != "$want runtime" ]; }; then
    target="$root"
    if [ "$mode" = "test" ]; then
        target="$root[test]"
    fi
    "$venv/bin/python" -m pip install --quiet --upgrade pip >&2
    "$venv/bin/python" -m pip install --quiet -e "$target" >&2
    echo "$want $mode" > "$stamp"
fi
export PATH="$venv/bin:$PATH"
