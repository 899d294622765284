"""The derivation of a bundled example through the derivation cache, for the tests whose
subject is what is done with a derivation (simulation, printing, the command line's twins,
the JSON document, consistent starts), not the symbolic derivation itself: each example is
then derived once per test run instead of once per test process (issue 46 §6).

Why this weakens no test: the run's cache starts empty (tests/conftest.py ``_shared_cache``,
scripts/test.sh, .ci/run) and an entry's key holds the digest of appell's own source, so
every derivation read here was derived by this run's code, in this or another test process
(the first test to ask derives it); a derivation read back gives the same numbers in every
block to 1e-15 and the same formulas as a fresh one (tests/test_derivation_cache.py), and a
test that reads one also checks the cache's decoding. The comparisons that need an
independent derivation keep theirs (a builder's system, another route)."""

from __future__ import annotations

from pathlib import Path

from appell.examples import example_path


def bundled_derivation(name, formulas: bool = False):
    """:func:`appell.workflows.load_derivation` of the bundled example ``name`` (or of the file
    at the path ``name``, e.g. the bundled arm.urdf; the command
    line's route: :func:`appell.derive`, or :func:`appell.control.servo.derive_controlled` for
    servo constraints; the inertia checked at the start), its notes dropped; ``formulas``: the
    reduced equations and reaction formulas computed too."""
    from appell.workflows import load_derivation

    path = name if isinstance(name, Path) else example_path(name)
    return load_derivation(str(path), formulas=formulas, echo=lambda *a, **k: None)
