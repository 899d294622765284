"""The suite's own setup (tests/conftest.py, scripts/test.sh, issue 46 §6): the module lists
that select passes, variants and the workers' order name modules that exist (a renamed module
would silently leave its pass, the numerical variants or the long-first order), and the run's
derivation and compiled-code cache is a folder of the run's own, never the user's."""

from __future__ import annotations

import os
from pathlib import Path

import conftest

TESTS = Path(__file__).resolve().parent


def test_every_listed_module_exists():
    modules = {p.name for p in TESTS.glob("test_*.py")}
    for name, listed in (
        ("SERIAL", conftest.SERIAL),
        ("HEAVY", conftest.HEAVY),
        ("NOT_NUMERICAL", conftest.NOT_NUMERICAL),
        ("LONGEST_FIRST", set(conftest.LONGEST_FIRST)),
    ):
        assert listed <= modules, f"{name} names missing modules: {sorted(listed - modules)}"


def test_the_long_modules_are_handed_out_first():
    """Every heavy module is in the long-first order, once."""
    order = conftest.LONGEST_FIRST
    assert set(order) == conftest.HEAVY and len(order) == len(set(order))


def test_the_run_has_a_cache_of_its_own():
    cache = os.environ.get("APPELL_CACHE_DIR")
    assert cache, "tests/conftest.py sets $APPELL_CACHE_DIR for the run"
    assert Path(cache).resolve() != (Path.home() / ".cache" / "appell").resolve()
