"""Shared fixtures: the documentation built once per test session (Sphinx, warnings are
errors), used by tests/test_docs.py and tests/test_docs_offline.py; a real Dask cluster of
separate processes (tests/test_faults.py, tests/test_sweep.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"


@pytest.fixture(scope="session")
def docs_build(tmp_path_factory):
    """``(CompletedProcess, html folder)`` of ``sphinx-build -W --keep-going -b html docs``,
    built once for the whole run: the pytest-xdist workers share it through a folder beside
    their own temporary folders, the first to ask building it under a lock (fcntl) while the
    other waits (the build runs every bundled example for the gallery's figures: 45 s)."""
    import fcntl
    import json

    pytest.importorskip("sphinx", reason="sphinx is not installed (pip install -e '.[docs]')")
    pytest.importorskip("myst_parser", reason="myst-parser is not installed (pip install -e '.[docs]')")
    base = tmp_path_factory.getbasetemp()  # a worker's is <run's folder>/popen-gwN
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "docs-shared"
    root.mkdir(exist_ok=True)
    out, record = root / "html", root / "result.json"
    with open(root / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not record.exists():
                env = {**os.environ, "MPLBACKEND": "Agg"}
                done = subprocess.run(
                    [
                        sys.executable,
                        "-m",
                        "sphinx",
                        "-W",
                        "--keep-going",
                        "-q",
                        "-b",
                        "html",
                        "-d",
                        str(root / "doctrees"),
                        str(DOCS),
                        str(out),
                    ],
                    capture_output=True,
                    text=True,
                    timeout=600,
                    env=env,
                )
                record.write_text(json.dumps([done.args, done.returncode, done.stdout, done.stderr]))
            args, code, stdout, stderr = json.loads(record.read_text())
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return subprocess.CompletedProcess(args, code, stdout, stderr), out


@pytest.fixture
def dask_processes(tmp_path):
    """A 'dask scheduler' process on a free port; ``.workers(n)`` starts 'dask worker'
    processes. All are killed when the test ends (:class:`processes.DaskProcesses`)."""
    from processes import DaskProcesses

    procs = DaskProcesses(tmp_path)
    yield procs
    procs.close()


# ------------------------------------------------------------------ variants (scripts/test-matrix.sh)
#: the numerical part of the suite: closed forms, published values, independent routes.
#: Left out: the browser, packaging, documentation, CLI-text and hostile-input tests, whose
#: outcome does not depend on rounding (``pytest -m numerical`` selects the rest); likewise
#: the tests of what is imported (test_cli_imports, test_fast_default: ``sys.modules`` and the
#: default backend's class in a child process; test_missing_extras: the refusal of a missing
#: package; test_typing: the lazy names against their ``TYPE_CHECKING`` block) and of the
#: source's sizes (test_layout), which compare names, strings and line counts, no number.
NOT_NUMERICAL = {
    "test_api_misuse.py",
    "test_architecture.py",
    "test_benchmark_references.py",
    "test_cli.py",
    "test_cli_imports.py",
    "test_cli_solver.py",
    "test_core_bad_input.py",
    "test_core_printing.py",
    "test_display.py",
    "test_docs.py",
    "test_docs_offline.py",
    "test_fast_default.py",
    "test_faults.py",
    "test_json_exact.py",
    "test_layout.py",
    "test_matrix_script.py",
    "test_mechanism_errors.py",
    "test_missing_extras.py",
    "test_modelfile_hostile.py",
    "test_packaging.py",
    "test_report_browser.py",
    "test_servo_bad_input.py",
    "test_suite_setup.py",
    "test_sweep.py",
    "test_typing.py",
    "test_urdf_hostile.py",
    "test_viewer_browser.py",
}

#: ``$APPELL_TEST_BACKEND=c``: ``numeric_model(derivation)`` is the compiled C model
#: (:func:`appell.compile_c`) for the whole session, so that every test that reads
#: ``numeric_model(derivation)`` runs its numbers through the C split; the default is NumPy
#: (the library's own default is 'auto', C where a compiler is found: the suite names the
#: backend it checks, and tests/test_fast_default.py checks the library's default)
BACKEND = os.environ.get("APPELL_TEST_BACKEND", "numpy")


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "numerical: a closed-form, published-value or cross-route test (selected by scripts/test-matrix.sh)"
    )
    config.addinivalue_line(
        "markers",
        "numpy_model: the test mutates or inspects the NumPy model itself (kept on NumPy under APPELL_TEST_BACKEND=c)",
    )
    config.addinivalue_line(
        "markers", "slow: a long run (e.g. the full fuzz of tests/test_fuzz.py), skipped unless APPELL_SLOW=1"
    )
    if BACKEND not in ("numpy", "c"):
        raise pytest.UsageError(f"APPELL_TEST_BACKEND must be 'numpy' or 'c', got {BACKEND!r}")
    _use_backend(BACKEND)
    config.stash[_OWN_CACHE] = _shared_cache()


#: the cache folder this process made (:func:`_shared_cache`), removed when pytest ends
_OWN_CACHE = pytest.StashKey[str | None]()


def _shared_cache() -> str | None:
    """One derivation and compiled-code cache for the whole run (``$APPELL_CACHE_DIR``):
    unless the caller set it (scripts/test.sh for both its passes, .ci/run for the suite and
    the BLAS variant), a new temporary folder, made by the first pytest process of the run
    (the pytest-xdist workers and every child process inherit the variable), so that each
    bundled example is derived and compiled once per run, not once per process, and the run
    starts from an empty cache and leaves the user's ~/.cache/appell alone. The tests of
    the caches themselves point the variable at folders of their own. Returns the folder
    made here, or None."""
    if os.environ.get("APPELL_CACHE_DIR"):
        return None
    path = tempfile.mkdtemp(prefix="appell-test-cache.")
    os.environ["APPELL_CACHE_DIR"] = path
    return path


def pytest_unconfigure(config):
    own = config.stash.get(_OWN_CACHE, None)
    if own:
        os.environ.pop("APPELL_CACHE_DIR", None)
        shutil.rmtree(own, ignore_errors=True)


def _use_backend(backend: str):
    """Every ``numeric_model(derivation)`` without a backend gives the model of ``backend``."""
    from appell.numerics import boundary

    boundary.DEFAULT_BACKEND = backend
    os.environ["APPELL_BACKEND"] = backend  # the same in the child processes (docs, command lines)


#: ``$APPELL_SLOW=1``: run the tests marked ``slow`` too
SLOW = os.environ.get("APPELL_SLOW") == "1"

#: modules whose tests time child processes, signals or alarms: scripts/test.sh runs them
#: in a pass of their own after the rest has run on two workers, so that the other worker's
#: load cannot stretch a Ctrl-C's or a timeout's timing (a SIGINT test's child outlived its
#: 60 s under pytest-xdist on a loaded machine). test_symbolic_bounds.py runs with the rest: its
#: hang guard (60 s) is 12 times its slowest test's 5 s
SERIAL = {"test_boundary_values.py", "test_faults.py", "test_fuzz.py", "test_sweep.py"}
#: ``$APPELL_TEST_PART``: ``parallel`` (every module but :data:`SERIAL`), ``serial`` (those
#: only), or unset (all)
PART = os.environ.get("APPELL_TEST_PART", "")
#: ``$APPELL_QUICK=1`` (``bash scripts/test.sh --quick``): the everyday subset, about 2.5 minutes
#: on two cores: every module but :data:`SERIAL` and these, which derive the large models
#: (the bicycle, the URDF arm, the IFToMM chains), run every bundled example, build the
#: documentation or drive a browser or subprocesses (9 s to 140 s each on two cores)
HEAVY = {
    "test_docs.py",
    "test_docs_offline.py",
    "test_cli.py",
    "test_iftomm.py",
    "test_modelfile_examples.py",
    "test_printed_equations.py",
    "test_servo_drive.py",
    "test_json_exact.py",
    "test_viewer_browser.py",
    "test_bicycle.py",
    "test_matrix_script.py",
    "test_inverse.py",
    "test_evidence.py",
    "test_result_schema.py",
    "test_mjcf.py",
    "test_implicit_jacobian.py",
    "test_urdf_pinocchio.py",
    "test_report_browser.py",
    "test_cli_solver.py",
    "test_symbolic_bounds.py",
    "test_api_cli_agree.py",
    "test_tree_route.py",
    "test_derivation_cache.py",
    "test_mjcf_menagerie.py",
    "test_paper_forms.py",
    "test_inverse_contacts.py",
    "test_printed_recursion.py",
    "test_parallel_gripper.py",
    "test_loops.py",
    "test_rigid_tree.py",
}
QUICK = os.environ.get("APPELL_QUICK") == "1"
#: the order in which the parallel pass hands modules to its workers (scripts/passes.sh gives
#: pytest-xdist ``--no-loadscope-reorder``, whose default hands out the modules with the most
#: tests first, the long ones with few tests last): the longest first, so that the last module
#: to finish is a short one and no worker waits alone at the end; the other modules follow in
#: their usual order. By each module's time in one process (the parallel pass's modules, a
#: shared cache filled as the run goes, 2026-11-29): test_iftomm.py 260 s (its printed 20 x 20
#: chain alone 93 s), the Sphinx build of test_docs_offline.py (:func:`docs_build`, every
#: bundled example run for the gallery's figures) 80 s, down to 2 s.
LONGEST_FIRST = (
    "test_iftomm.py",
    "test_docs.py",
    "test_docs_offline.py",
    "test_api_cli_agree.py",
    "test_printed_equations.py",
    "test_viewer_browser.py",
    "test_cli.py",
    "test_loops.py",
    "test_matrix_script.py",
    "test_rigid_tree.py",
    "test_derivation_cache.py",
    "test_inverse.py",
    "test_implicit_jacobian.py",
    "test_bicycle.py",
    "test_modelfile_examples.py",
    "test_mjcf_menagerie.py",
    "test_mjcf.py",
    "test_symbolic_bounds.py",
    "test_urdf_pinocchio.py",
    "test_servo_drive.py",
    "test_result_schema.py",
    "test_json_exact.py",
    "test_cli_solver.py",
    "test_tree_route.py",
    "test_inverse_contacts.py",
    "test_printed_recursion.py",
    "test_evidence.py",
    "test_report_browser.py",
    "test_paper_forms.py",
    "test_parallel_gripper.py",
)


def pytest_ignore_collect(collection_path, config):
    """In a pass of scripts/test.sh (:data:`PART`), the other pass's modules are not even
    imported (collecting all 1,500 tests to deselect most of them took the serial pass 10 s);
    ``--quick`` skips the heavy ones likewise, and ``-m numerical`` the modules of
    :data:`NOT_NUMERICAL`. None: pytest decides as usual."""
    name = collection_path.name
    if not (name.startswith("test_") and name.endswith(".py")):
        return None
    if PART and (name in SERIAL) != (PART == "serial"):
        return True
    if QUICK and name in HEAVY | SERIAL:
        return True
    if name in NOT_NUMERICAL and config.getoption("markexpr", "") == "numerical":
        return True  # the matrix's variants (pytest -m numerical) would deselect every test of it
    return None


def pytest_collection_modifyitems(config, items):
    if PART not in ("", "parallel", "serial"):
        raise pytest.UsageError(f"APPELL_TEST_PART must be 'parallel' or 'serial', got {PART!r}")
    # the modules of the other pass, and --quick's heavy ones, are not collected (pytest_ignore_collect),
    # but a module named on the command line is collected anyway: its tests run in their own pass only
    if PART:
        other = [item for item in items if (item.path.name in SERIAL) != (PART == "serial")]
        if other:
            config.hook.pytest_deselected(items=other)
            items[:] = [item for item in items if (item.path.name in SERIAL) == (PART == "serial")]
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: each module's own order kept
    skip_slow = pytest.mark.skip(reason="a long run: set APPELL_SLOW=1 to run it")
    for item in items:
        if item.path.name not in NOT_NUMERICAL:
            item.add_marker(pytest.mark.numerical)
        if not SLOW and item.get_closest_marker("slow"):
            item.add_marker(skip_slow)


@pytest.fixture(autouse=True)
def _numpy_model_where_marked(request, monkeypatch):
    """Under ``APPELL_TEST_BACKEND=c``, a test marked ``numpy_model`` gets the NumPy model
    back (it mutates the NumPy blocks, which the C split does not call)."""
    if BACKEND == "c" and request.node.get_closest_marker("numpy_model"):
        from appell.numerics import boundary

        monkeypatch.setattr(boundary, "DEFAULT_BACKEND", "numpy")
    yield
