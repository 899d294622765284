"""Fast by default (issue 46 §1, §3): the API's default backend is the command line's 'auto'
(compiled C where a compiler is found, else NumPy with a warning), NumPy stays available by
name, and ``import appell`` imports none of SymPy, SciPy, xarray, pandas, matplotlib, h5py or
Dask (their import is what made ``import appell`` cost 3x ``import sympy``).

Each check runs in a fresh interpreter (a subprocess) without ``$APPELL_BACKEND``, which the
test suite sets to the backend it checks (tests/conftest.py); the source of truth is
``sys.modules`` and the model's class.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from appell.numerics.codegen import find_compiler

HEAVY = ("sympy", "scipy", "xarray", "pandas", "matplotlib", "h5py", "dask", "appell.io.cli", "appell.io.viewer")


def _run(code: str, **env) -> str:
    clean = {k: v for k, v in os.environ.items() if k != "APPELL_BACKEND"}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, env={**clean, **env}
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().splitlines()[-1]


def test_import_appell_imports_no_heavy_library():
    out = _run(f"import sys, appell; print([m for m in {HEAVY!r} if m in sys.modules])")
    assert out == "[]"


def test_the_pipeline_names_import_no_data_or_plotting_library():
    code = (
        "import sys\nfrom appell import derive, load_model, numeric_model, simulate, System\n"
        "print([m for m in ('xarray', 'pandas', 'matplotlib', 'h5py', 'dask', 'appell.io.viewer') "
        "if m in sys.modules])"
    )
    assert _run(code) == "[]"


def test_public_names_and_submodules_as_attributes():
    import appell

    assert set(appell.__all__) <= set(dir(appell))
    for name in appell.__all__:
        assert getattr(appell, name) is not None, name
    assert appell.numerics.boundary.numeric_model is appell.numeric_model
    with pytest.raises(AttributeError):
        appell.no_such_name  # noqa: B018
    with pytest.raises(AttributeError):
        appell.numerics.no_such_module  # noqa: B018


MODEL = """
import warnings
import appell
from appell.numerics.codegen import CompiledNumericModel
from appell.numerics.numeric import NumericModel
d = appell.derive(appell.load_model("pendulum"))
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    m = appell.numeric_model(d)
kind = "c" if isinstance(m, CompiledNumericModel) else "numpy" if isinstance(m, NumericModel) else type(m).__name__
named = type(appell.numeric_model(d, "numpy")).__name__
print(kind, named, sum("no C compiler" in str(w.message) for w in caught))
"""


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_the_default_backend_is_compiled_where_a_compiler_is_found(tmp_path):
    assert _run(MODEL, APPELL_CACHE_DIR=str(tmp_path)) == "c NumericModel 0"


def test_without_a_compiler_the_default_is_numpy_with_one_warning(tmp_path):
    assert _run(MODEL, APPELL_CC=str(tmp_path / "no-such-cc"), APPELL_CACHE_DIR=str(tmp_path)) == "numpy NumericModel 1"


def test_appell_backend_names_another_default(tmp_path):
    assert _run(MODEL, APPELL_BACKEND="numpy").startswith("numpy ")


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler: 'auto' is NumPy anyway")
def test_the_command_lines_numpy_backend_stays_numpy():
    """``appell simulate --backend numpy`` (workflows.run_simulation) runs the NumPy model by
    name: with the default now 'auto', passing the bare derivation on compiled C instead."""
    code = (
        "from appell import derive, load_model\nfrom appell.numerics import boundary\n"
        "from appell.workflows import run_simulation\n"
        "d = derive(load_model('pendulum'))\nrun_simulation(d, 0.01, backend='numpy')\n"
        "print(boundary._kept(d, 'c') is None and boundary._kept(d, 'numpy') is not None)"
    )
    assert _run(code) == "True"


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler: the run integrates in Python")
def test_a_compiled_run_imports_no_scipy_integrate():
    """``appell simulate`` of a compiled model runs the compiled loop: SciPy's integrators are
    imported only by a run that integrates in Python (``--method DOP853-scipy`` here, which
    shows that the check sees the import)."""
    code = (
        "import sys\nfrom appell.io.cli import main\n"
        "sys.argv = ['appell', 'simulate', 'pendulum', '--t-end', '0.2', *sys.argv[1:]]\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    print(exc.code, 'scipy.integrate' in sys.modules)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "APPELL_BACKEND"}
    seen = []
    for extra in ([], ["--method", "DOP853-scipy"]):
        done = subprocess.run([sys.executable, "-c", code, *extra], capture_output=True, text=True, env=env)
        seen.append(done.stdout.strip().splitlines()[-1])
    assert seen == ["0 False", "0 True"], seen
