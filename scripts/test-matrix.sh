#!/usr/bin/env bash
# The numerical part of the test suite (pytest -m numerical: closed forms, published values,
# independent routes) under each BLAS kernel this CPU supports and with both numeric
# backends, then a table of passes and failures per variant (issue 26). Each variant runs in
# scripts/test.sh's two passes (scripts/passes.sh: $APPELL_TEST_WORKERS workers, default 2,
# then the serial modules alone), all variants with one derivation and compiled-code cache. A test whose
# tolerance holds only under one machine's rounding fails here where it is written.
#
# Usage: bash scripts/test-matrix.sh [--kernels "unset Haswell Nehalem Prescott"]
#                                    [--backends "numpy c"] [--margins] [-- PYTEST ARGS]
#   --margins   also report, per variant, the comparisons that use more than a tenth of
#               their tolerance (tests/tolerance_margins.py)
# Exit status: 0 when every variant passes, 1 otherwise.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh" test
cd "$(dirname "${BASH_SOURCE[0]}")/.."

kernels="unset Haswell Nehalem Prescott"
backends="numpy c"
margins=""
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --kernels) kernels="$2"; shift 2 ;;
        --backends) backends="$2"; shift 2 ;;
        # the plugin counts in its own process: one process per pass, no pytest-xdist workers
        --margins) margins="-p tolerance_margins"; export APPELL_TEST_WORKERS=1; shift ;;
        --) shift; extra=("$@"); break ;;
        *) echo "unknown option $1 (see the head of $0)" >&2; exit 2 ;;
    esac
done

# OpenBLAS's x86-64 kernels need these instruction sets; a kernel the CPU lacks would crash
flags="$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null || true)"
supported() {
    case "$1" in
        unset) return 0 ;;
        Prescott) [[ "$flags" == *" sse3"* || "$flags" == *" pni"* ]] ;;
        Nehalem) [[ "$flags" == *" sse4_2"* ]] ;;
        Haswell|Zen) [[ "$flags" == *" avx2"* ]] ;;
        SkylakeX|Cooperlake) [[ "$flags" == *" avx512f"* ]] ;;
        *) return 1 ;;
    esac
}

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
source scripts/passes.sh
# one derivation and compiled-code cache for every variant (the kernel and the backend change
# the numbers, not the derivation nor the C source): scripts/passes.sh, shared_cache
shared_cache "$out/cache"
rows=()
status=0
for kernel in $kernels; do
    for backend in $backends; do
        name="OPENBLAS_CORETYPE=${kernel} backend=${backend}"
        if ! supported "$kernel"; then
            rows+=("$(printf '%-32s %-8s %s' "OPENBLAS_CORETYPE=$kernel" "$backend" "skipped: the CPU lacks this kernel's instructions")")
            continue
        fi
        echo "== $name" >&2
        xml="$out/${kernel}-${backend}"
        start=$(date +%s)
        # the two passes of scripts/test.sh (scripts/passes.sh): the serial modules on their own
        rc=0
        (if [ "$kernel" = unset ]; then unset OPENBLAS_CORETYPE; else export OPENBLAS_CORETYPE="$kernel"; fi
         export APPELL_TEST_BACKEND="$backend" PYTHONPATH=tests
         run_passes "$xml" -m numerical -p no:cacheprovider $margins "${extra[@]}") >&2 || rc=$?
        secs=$(( $(date +%s) - start ))
        if [ "$rc" -ne 0 ]; then status=1; fi
        rows+=("$(python - "$xml" "$kernel" "$backend" "$secs" "$rc" <<'EOF'
import sys
import xml.etree.ElementTree as ET

prefix, kernel, backend, secs, rc = sys.argv[1:]
counts = [0, 0, 0, 0]  # tests, failures, errors, skipped over the two passes' reports
read = 0
for part in ("parallel", "serial"):
    try:
        suite = ET.parse(f"{prefix}-{part}.xml").getroot()
    except (OSError, ET.ParseError):
        continue
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    counts = [c + int(suite.get(k, 0)) for c, k in zip(counts, ("tests", "failures", "errors", "skipped"))]
    read += 1
n, f, e, s = counts
if read:
    print(f"{'OPENBLAS_CORETYPE=' + kernel:32s} {backend:8s} {n:6d} {n - f - e - s:7d} {f + e:7d} {s:8d} {secs:>7s}s")
else:
    print(f"{'OPENBLAS_CORETYPE=' + kernel:32s} {backend:8s} pytest exited {rc} before writing its report")
EOF
)")
    done
done

echo
echo "numerical subset (pytest -m numerical) per variant, $(date -u +%Y-%m-%d), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
printf '%-32s %-8s %6s %7s %7s %8s %8s\n' "variant" "backend" "tests" "passed" "failed" "skipped" "time"
for row in "${rows[@]}"; do echo "$row"; done
exit $status
