"""scripts/test-matrix.sh (issue 26): the numerical part of the suite under several BLAS
kernels and both backends, with a table of passes and failures per variant. Run here on
one small test so that the table, the exit status and the variant selection are checked."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "test-matrix.sh"


def matrix(*args, timeout=300, workers="2"):
    """The script with ``$APPELL_TEST_WORKERS`` = ``workers`` (its first pass's pytest-xdist workers)."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "APPELL_TEST_BACKEND")}
    env["APPELL_TEST_WORKERS"] = workers
    return subprocess.run(
        ["bash", str(SCRIPT), *args], capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT
    )


@pytest.mark.skipif(not Path("/proc/cpuinfo").exists(), reason="reads the CPU's instruction sets from /proc/cpuinfo")
def test_matrix_prints_one_row_per_variant_and_passes():
    done = matrix(
        "--kernels",
        "Prescott",
        "--backends",
        "numpy c",
        "--",
        "tests/test_partition_singular.py",
        "-k",
        "one_by_one",
        workers="1",
    )  # one process a pass: the workers' start is not the point (the whole suite runs on them)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith("OPENBLAS_CORETYPE=")]
    assert [(r[0], r[1]) for r in rows] == [
        ("OPENBLAS_CORETYPE=Prescott", "numpy"),
        ("OPENBLAS_CORETYPE=Prescott", "c"),
    ]
    for r in rows:  # tests, passed, failed, skipped
        assert r[2] == r[3] == "1" and r[4] == "0", done.stdout


def test_matrix_fails_when_a_variant_fails_and_says_which():
    """A deliberately failing selection (an expression that matches no numerical test makes
    pytest exit 5) gives exit 1 and a row that says pytest stopped."""
    done = matrix(
        "--kernels",
        "unset",
        "--backends",
        "numpy",
        "--",
        "tests/test_partition_singular.py",
        "-k",
        "no_test_has_this_name",
        workers="1",
    )  # one process: the workers' start is not the point here
    assert done.returncode == 1
    assert "OPENBLAS_CORETYPE=unset" in done.stdout


def test_matrix_refuses_an_unknown_option():
    done = matrix("--colour")
    assert done.returncode == 2 and "unknown option --colour" in done.stderr
