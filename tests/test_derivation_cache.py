"""The derivation cache (appell.io.derivation_cache, issue 46 §2).

Source of truth: a fresh derivation of the same model file in the same process
(appell.derive of appell.load_model, no cache): the cached one must give the same numbers in
every block (M, h - Q, J, c, the coordinate rates, the accelerations, multipliers and
outputs) at random states, to 1e-15 relative, and the same reduced equations and reaction
formulas (structural SymPy equality). A tampered, truncated or foreign entry must be ignored
with a note and rebuilt; two processes filling one entry at once must both get the model.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import appell
from appell.errors import AppellNote, ModelError
from appell.examples import example_path
from appell.io import derivation_cache as dc


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv(dc.NO_CACHE_ENV, raising=False)
    return tmp_path / "derivations"


def _entries(folder: Path) -> list[Path]:
    return sorted(folder.glob("*.json"))


def _same_numbers(fresh, cached, seed=0):
    a, b = appell.numeric_model(fresh, "numpy"), appell.numeric_model(cached, "numpy")
    assert a.state_names == b.state_names and a.parameter_names == b.parameter_names
    rng = np.random.default_rng(seed)
    n, nq = len(a.speed_names), len(a.coordinate_names)
    for _ in range(3):
        t, q, w = rng.uniform(0, 1), rng.uniform(-1, 1, nq), rng.uniform(-1, 1, n)
        for x, y in zip(a.evaluate_blocks(t, q, w), b.evaluate_blocks(t, q, w)):
            np.testing.assert_allclose(y, x, rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(b.coordinate_rates(t, q, w), a.coordinate_rates(t, q, w), rtol=1e-15, atol=1e-15)
        sa, sb = a.solve(t, q, w), b.solve(t, q, w)
        for name in ("accelerations", "multipliers", "generalized_reactions"):
            np.testing.assert_allclose(getattr(sb, name), getattr(sa, name), rtol=1e-15, atol=1e-15)
        oa, ob = a.outputs(t, q, w, solution=sa), b.outputs(t, q, w, solution=sb)
        assert oa.keys() == ob.keys()
        np.testing.assert_allclose(list(ob.values()), list(oa.values()), rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("name", ["car", "four_bar", "table_four_legs", "rolling_disc"])
def test_a_cached_derivation_equals_a_fresh_one(cache, name):
    fresh = appell.derive(appell.load_model(name))
    first = dc.derive_file(name, formulas=True)  # derived and stored
    assert len(_entries(cache)) == 1
    second = dc.derive_file(name)  # read back
    assert second is not first
    assert {"reduced", "reactions"} <= set(vars(second))  # the formulas came with it
    _same_numbers(fresh, second)
    assert second.reduced == fresh.reduced and second.reactions == fresh.reactions
    assert second.system.parameters == fresh.system.parameters


def test_a_urdf_robot_from_the_cache(cache):
    path = Path(appell.__file__).parent / "examples" / "arm.urdf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AppellNote)
        fresh = appell.derive(appell.load_model(path))
        dc.derive_file(path)
        cached = dc.derive_file(path)
    assert cached.inertia.tree == fresh.inertia.tree
    _same_numbers(fresh, cached, seed=1)


def test_the_key_covers_the_content_the_overrides_and_the_partition(cache, tmp_path):
    source = example_path("pendulum").read_text()
    model = tmp_path / "p.toml"
    model.write_text(source)
    key = dc.entry_key(model)
    assert dc.entry_key(model, {"m": 2.0}) != key
    assert dc.entry_key(model, dependent=["x_ddot"]) != key
    model.write_text(source + "\n# a comment\n")
    assert dc.entry_key(model) != key
    d = dc.derive_file(model, {"m": 2.0})
    assert next(p.value for p in d.system.parameters if p.symbol.name == "m") == 2.0


def _stored(cache) -> Path:
    dc.derive_file("pendulum")
    (entry,) = _entries(cache)
    return entry


def _tampered(entry: Path, how: str) -> None:
    raw = entry.read_bytes()
    if how == "truncated":
        entry.write_bytes(raw[: len(raw) // 2])
    elif how == "tampered":  # one number changed, the checksum left as it was
        head, body = raw.split(b"\n", 1)
        entry.write_bytes(head + b"\n" + body.replace(b'"Integer","2"', b'"Integer","3"', 1))
    elif how == "foreign":  # a valid entry of another model under this one's name
        other = dc.entry_key(example_path("four_bar"))
        dc.write_entry(entry.parent, entry, other, appell.derive(appell.load_model("four_bar")))
    elif how == "empty":
        entry.write_bytes(b"")
    elif how == "code":  # a well-formed entry naming a class outside appell
        head, body = raw.split(b"\n", 1)
        body = body.replace(b'"appell.model:System"', b'"os:system"', 1)
        import hashlib
        import json

        header = json.loads(head)
        header["sha256"] = hashlib.sha256(body).hexdigest()
        entry.write_bytes(json.dumps(header).encode() + b"\n" + body)


@pytest.mark.parametrize("how", ["truncated", "tampered", "foreign", "empty", "code"])
def test_a_bad_entry_is_ignored_with_a_note_and_rebuilt(cache, how):
    entry = _stored(cache)
    good = entry.read_bytes()
    _tampered(entry, how)
    assert entry.read_bytes() != good
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = dc.derive_file("pendulum")
    notes = [str(w.message) for w in caught if issubclass(w.category, AppellNote)]
    assert len(notes) == 1 and "ignored" in notes[0] and str(entry) in notes[0], notes
    _same_numbers(appell.derive(appell.load_model("pendulum")), d)
    assert entry.read_bytes() == good  # rebuilt
    with warnings.catch_warnings():
        warnings.simplefilter("error", AppellNote)
        dc.derive_file("pendulum")  # and trusted again without a note


def test_no_cache_switch_reads_and_writes_nothing(cache, monkeypatch):
    monkeypatch.setenv(dc.NO_CACHE_ENV, "1")
    dc.derive_file("pendulum")
    assert not cache.exists() or not _entries(cache)
    monkeypatch.delenv(dc.NO_CACHE_ENV)
    dc.derive_file("pendulum", cache=False)
    assert not cache.exists() or not _entries(cache)


def test_the_size_bound_removes_the_least_recently_used(cache):
    import os

    dc.derive_file("pendulum")
    dc.derive_file("four_bar")
    old, new = sorted(_entries(cache), key=lambda p: p.stat().st_mtime)
    os.utime(old, (1, 1))
    dc.evict(cache, limit_bytes=new.stat().st_size)
    assert _entries(cache) == [new]


CHILD = """
import json, sys, numpy as np, appell
from appell.io.derivation_cache import derive_file
d = derive_file("four_bar")
m = appell.numeric_model(d, "numpy")
q = np.full(len(m.coordinate_names), 0.3); w = np.full(len(m.speed_names), 0.2)
print(json.dumps(m.solve(0.0, q, w).multipliers.tolist()))
"""


def test_two_processes_filling_one_entry_both_get_the_model(cache):
    import os

    from appell.core.derive import derive as derive_now  # a fresh derivation, not a cached one

    env = {**os.environ, "APPELL_CACHE_DIR": str(cache.parent)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CHILD], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err for _, err in outs]
    assert all("note" not in err.lower() for _, err in outs), [err for _, err in outs]
    m = appell.numeric_model(derive_now(appell.load_model("four_bar")), "numpy")
    q, w = np.full(len(m.coordinate_names), 0.3), np.full(len(m.speed_names), 0.2)
    expected = m.solve(0.0, q, w).multipliers
    for out, _ in outs:
        np.testing.assert_allclose(json.loads(out.strip().splitlines()[-1]), expected, rtol=1e-15, atol=1e-15)
    assert len(_entries(cache)) == 1


def test_the_notes_of_reading_a_file_come_again_from_the_cache(cache, tmp_path):
    """A URDF joint's <dynamics> is not applied (an AppellNote when the file is read): the
    second run, from the cache, gives the same note."""
    urdf = tmp_path / "arm.urdf"
    source = (Path(appell.__file__).parent / "examples" / "arm.urdf").read_text()
    joint_end = source.index("</joint>")
    urdf.write_text(source[:joint_end] + '<dynamics damping="0.5"/>' + source[joint_end:])
    runs = []
    for _ in range(2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            dc.derive_file(urdf)
        runs.append([str(w.message) for w in caught if issubclass(w.category, AppellNote)])
    assert len(_entries(cache)) == 1
    assert runs[0] and runs[1] == runs[0] and "dynamics" in runs[0][0]


def test_a_check_runs_before_storing_and_not_again_on_a_checked_entry(cache):
    """derive_file(check=...): run on the fresh derivation before it is stored, skipped when
    the entry records that it passed, run on an entry stored without it; a derivation the
    check refuses is not stored (the command line's inertia check, issue 46: a second run
    does not build the NumPy model for it)."""
    calls = []

    def check(derivation):
        calls.append(derivation.system.name)

    def refuse(derivation):
        raise ModelError("refused by the check")

    with pytest.raises(ModelError, match="refused"):
        dc.derive_file("pendulum", check=refuse)
    assert _entries(cache) == []  # nothing stored
    dc.derive_file("pendulum", check=check)
    assert len(calls) == 1 and len(_entries(cache)) == 1
    _same_numbers(dc.derive_file("pendulum", check=check), dc.derive_file("pendulum", cache=False))
    assert len(calls) == 1  # the entry passed it
    dc.derive_file("particle_on_sphere")  # stored without a check
    dc.derive_file("particle_on_sphere", check=check)
    assert len(calls) == 2
    with pytest.raises(ModelError, match="refused"):  # an unchecked entry is checked when read
        dc.derive_file("particle_on_sphere", check=refuse)


SYSTEM_CHILD = """
import sys, appell
from appell.examples.mechanism_examples import rolling_disc
appell.derive(rolling_disc())
appell.derive(appell.load_model("four_bar"), dependent=sys.argv[1:])
"""


def test_a_system_built_in_python_and_derived_in_another_process_is_read_back(cache, monkeypatch):
    """appell.derive of a System built in Python (the rolling disc's builder; a model file's
    System with a chosen partition) is kept under the system's content: derived in a child
    process, it is read back here without deriving (the pipeline's derive raises), with the
    caller's own System, and every block, rate and solve equals a fresh derivation's (1e-15)."""
    from appell.core import derive as core
    from appell.examples.mechanism_examples import rolling_disc

    fresh_disc, bar = core.derive(rolling_disc()), appell.load_model("four_bar")
    dependent = [str(q) for q in bar.coordinates[-2:]]  # not the partition chosen by default
    fresh_bar = core.derive(bar, dependent)
    env = {**os.environ, "APPELL_CACHE_DIR": str(cache.parent)}
    child = subprocess.run(
        [sys.executable, "-c", SYSTEM_CHILD, *dependent], env=env, capture_output=True, text=True, timeout=300
    )
    assert child.returncode == 0, child.stderr
    assert len(_entries(cache / "systems")) == 2

    def refuse(*args, **kwargs):
        raise AssertionError("derived again: the stored derivation was not read")

    monkeypatch.setattr(core, "derive", refuse)
    disc = rolling_disc()
    cached_disc, cached_bar = appell.derive(disc), appell.derive(bar, dependent=tuple(dependent))
    assert cached_disc.system is disc and cached_bar.system is bar
    assert cached_bar.partition.dependent == fresh_bar.partition.dependent
    _same_numbers(fresh_disc, cached_disc)
    _same_numbers(fresh_bar, cached_bar, seed=1)


def test_derive_without_the_cache_for_another_system_or_a_refused_one(cache, monkeypatch):
    """appell.derive derives again with cache=False or $APPELL_NO_CACHE=1 and writes nothing;
    another parameter value is another entry; a system derive refuses raises as before and
    leaves no entry."""
    import dataclasses

    from appell.core import derive as core

    calls = []
    derive_now = core.derive
    monkeypatch.setattr(core, "derive", lambda *a, **k: calls.append(1) or derive_now(*a, **k))
    system = appell.load_model("pendulum")
    appell.derive(system, cache=False)
    monkeypatch.setenv(dc.NO_CACHE_ENV, "1")
    appell.derive(system)
    assert len(calls) == 2 and not (cache / "systems").exists()
    monkeypatch.delenv(dc.NO_CACHE_ENV)
    appell.derive(system)
    appell.derive(system)
    heavier = dataclasses.replace(
        system, parameters=tuple(dataclasses.replace(p, value=2 * p.value) for p in system.parameters)
    )
    appell.derive(heavier)
    assert len(calls) == 4 and len(_entries(cache / "systems")) == 2
    with pytest.raises(ModelError, match="servo constraints"):
        appell.derive(appell.load_model("slider_crank_drive"))
    assert len(_entries(cache / "systems")) == 2


def test_a_controlled_system_is_read_back_with_its_control_laws(cache, monkeypatch):
    """appell.derive_controlled through the cache: the second call reads the entry (the
    pipeline's derive_controlled raises) and its control laws are the fresh ones."""
    from appell.control import servo

    system = appell.load_model("slider_crank_drive")
    fresh = servo.derive_controlled(system)
    appell.derive_controlled(system)

    def refuse(*args, **kwargs):
        raise AssertionError("derived again: the stored derivation was not read")

    monkeypatch.setattr(servo, "derive_controlled", refuse)
    cached = appell.derive_controlled(system)
    assert cached.system is system
    assert cached.control_laws == fresh.control_laws


PRINT_CHILD = """
import json, sys, appell
from appell.io.derivation_cache import derive_file
d = derive_file("car")
print(json.dumps([appell.to_text(d), appell.to_latex(d), json.dumps(appell.to_json(d), sort_keys=True)]))
"""


def _printed(d) -> list[str]:
    return [appell.to_text(d), appell.to_latex(d), json.dumps(appell.to_json(d), sort_keys=True)]


def test_printed_forms_printed_in_another_process_come_back_equal_to_a_fresh_print(cache, monkeypatch):
    """A derivation's printed equations and JSON document are kept beside it
    (:func:`appell.io.derivation_cache.remembered`, under the derivation's content): printed
    in a child process, they are read back here without forming them again (forming them
    raises), and the text, LaTeX and JSON equal a fresh print with the cache off."""
    from appell.io import printing

    env = {**os.environ, "APPELL_CACHE_DIR": str(cache.parent)}
    child = subprocess.run([sys.executable, "-c", PRINT_CHILD], env=env, capture_output=True, text=True, timeout=300)
    assert child.returncode == 0, child.stderr
    assert len(_entries(cache / "printed")) == 2  # the printed equations and the JSON document
    d = dc.derive_file("car")

    def refuse(*args, **kwargs):
        raise AssertionError("formed again: the stored forms were not read")

    with monkeypatch.context() as m:
        m.setattr(printing, "form_printed_equations", refuse)
        m.setattr(printing, "_document", refuse)
        from_disk = _printed(d)
    assert from_disk == json.loads(child.stdout)
    monkeypatch.setenv(dc.NO_CACHE_ENV, "1")
    assert _printed(dc.derive_file("car")) == from_disk


PRINT_AT_ONCE_CHILD = """
import sys, time, appell
from pathlib import Path
from appell.io import printing
from appell.io.derivation_cache import derive_file
log, me = Path(sys.argv[1]), sys.argv[2]
d = derive_file("four_bar")
form = printing.form_printed_equations
def logged(*args, **kwargs):
    with log.open("a") as fh:
        fh.write(me + "\\n")
    time.sleep(1.0)  # the other process asks for the same forms meanwhile
    return form(*args, **kwargs)
printing.form_printed_equations = logged
(log.parent / me).touch()  # both ready, then both print at once
while not all((log.parent / k).exists() for k in ("a", "b")):
    time.sleep(0.01)
print(appell.to_text(d))
"""


def test_two_processes_printing_one_model_at_once_print_it_once(cache, tmp_path):
    """Two processes that print the same derivation at the same moment: one forms the printed
    equations, the other waits for its entry (the entry's lock) and reads it; both print the same
    text."""
    dc.derive_file("four_bar")  # the derivation stored: the children only read it
    env = {**os.environ, "APPELL_CACHE_DIR": str(cache.parent)}
    log = tmp_path / "formed"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", PRINT_AT_ONCE_CHILD, str(log), me],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for me in ("a", "b")
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err for _, err in outs]
    assert len(log.read_text().split()) == 1, log.read_text()  # formed once, in one of them
    assert outs[0][0] == outs[1][0] and "lambda" in outs[0][0]


def test_a_bad_printed_entry_is_ignored_with_a_note_and_printed_again(cache):
    d = dc.derive_file("car")
    good = appell.to_text(d)
    (entry,) = _entries(cache / "printed")
    entry.write_bytes(entry.read_bytes()[:100])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        again = appell.to_text(dc.derive_file("car"))
    notes = [str(w.message) for w in caught if issubclass(w.category, AppellNote)]
    assert len(notes) == 1 and "cached printed form" in notes[0] and "printing again" in notes[0], notes
    assert again == good


def test_the_printed_forms_key_is_the_content_not_what_was_computed_since(cache):
    """The key of a printed form covers the derivation's fields, not the formulas computed
    from them afterwards (printing forms the reduced equations and reactions): the same key
    before and after, another for another model or another computation."""
    d = appell.derive(appell.load_model("car"))
    before = dc.content_key(d, "printed_equations")
    d.reduced, d.reactions  # noqa: B018 (computed and kept on the derivation)
    assert dc.content_key(d, "printed_equations") == before
    assert dc.content_key(d, "derivation_document") != before
    assert dc.content_key(appell.derive(appell.load_model("pendulum")), "printed_equations") != before
