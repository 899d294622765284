"""Shared fixtures: the documentation built once per test session (Sphinx, warnings are
errors), used by tests/test_docs.py and tests/test_docs_offline.py; a real Dask cluster of
separate processes (tests/test_faults.py, tests/test_sweep.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"


@pytest.fixture(scope="session")
def docs_build(tmp_path_factory):
    """``(CompletedProcess, html folder)`` of ``sphinx-build -W --keep-going -b html docs``."""
    pytest.importorskip("sphinx", reason="sphinx is not installed (pip install -e '.[docs]')")
    pytest.importorskip("myst_parser", reason="myst-parser is not installed (pip install -e '.[docs]')")
    root = tmp_path_factory.mktemp("docs")
    out = root / "html"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-d", str(root / "doctrees"),
         str(DOCS), str(out)], capture_output=True, text=True, timeout=600, env=env)
    return done, out


@pytest.fixture
def dask_processes(tmp_path):
    """A 'dask scheduler' process on a free port; ``.workers(n)`` starts 'dask worker'
    processes. All are killed when the test ends (:class:`processes.DaskProcesses`)."""
    from processes import DaskProcesses

    procs = DaskProcesses(tmp_path)
    yield procs
    procs.close()
