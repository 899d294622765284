"""Seeded fuzzing of the command line: mutated bundled model files through ``appell derive``
and ``appell check`` (issue 20).

Case ``seed`` takes the bundled model file ``EXAMPLES[seed % len(EXAMPLES)]`` and mutates it
with ``random.Random(seed)`` (:func:`mutate`), by one of

* ``text``: one to four characters deleted, inserted, replaced or a span duplicated (the
  alphabet of the model-file reader's hostile-input tests, tests/test_modelfile_hostile.py);
* ``lines``: lines deleted, duplicated or swapped;
* ``value``: one entry of the parsed document replaced (a random expression over the
  model's own names, an injection attempt of the hostile-input tests, an odd scalar or
  container) or deleted, the document written back by the hostile-input tests' writer;
* ``swell``: one expression of the model made to swell under symbolic work -- a power
  ``(e)^n`` up to the reader's exponent limit, ``(sin(q) + cos(q) + 1)^n`` added, nested
  ``exp``/``sin`` chains, a product of many sums, or ``(1 + q^2)^n`` factors.

Every case runs ``appell derive FILE`` and ``appell check FILE`` in-process (click's
``CliRunner``) from a fresh working folder, under a hang guard of :data:`BOUND` seconds
each (``SIGALRM``: a guard against unbounded work, not a speed measurement). Invariants
(:func:`violations`): no internal error ("internal error", "a bug in appell"), no Python
traceback, exit code 0, 1 or 2 with an ``error:`` line when nonzero, every run inside its
bound, and no file written outside the working folder (the bundled examples and, in a run
of its own, the repository root are listed before and after; HOME is an empty folder of
the case's that must stay empty but for the libraries' caches; appell's compiled-code
cache is pointed into the working folder).

The quick subset (:data:`QUICK` seeds) runs by default; the full :data:`FULL` cases run with
``APPELL_SLOW=1`` (marker ``slow``). A chunk can also be run by hand, writing one JSON line
per case for a report::

    python tests/test_fuzz.py START STOP results.jsonl

Last full run, 2026-11-27 at commit 9b1fc31 (seeds 0-1999, 2 commands each, 4000 runs,
1,887 s of runs on this project's 2-core machine, loaded by a second test run): derive exit
0 816 times and 2 (a clear refusal) 1,184 times; check 0 615, 1 161, 2 1,222 times; no
internal error, no traceback, no file written outside the working folder (two listings
changed while the examples' source was edited during the run: seeds 1782 and 1789, clean
when run again). Runs: median 0.012 s, 99th percentile 6.4 s. Two ran past the bound
(seeds 1807 and 1931: an energy balance of slow evaluations, a Newton solve each), since
bounded by the balance's 10 s of wall time (its span ends there, with a note); seed 1782's
check failed on rounding (a motion at rest with energies of 1e-50) and passes since. The
cases the first full run (2026-11-25) handed over are :data:`FIXED`.

Extreme values (issue 42, :func:`extreme_cases`: every parameter of every bundled file at
+-2^63, 1e-300, 1e300; ``python tests/test_fuzz.py 0 656 out.jsonl extreme``), first run
2026-11-29 on a machine loaded by several other runs: 656 cases, 1,312 runs; 4 internal
errors (singular augmented systems of the cross-checks) and 17 NumPy warnings (overflowing
error norms of the energy balance and of simulate, a vanishing-row test, a servo solve),
each fixed at its root and run again clean (:data:`EXTREME_FIXED`); 65 runs passed the
20 s hang guard in wall time alone (the andrews squeezer's, rolling disc's and the drives'
symbolic stages under that load: a derive's CPU time does not depend on the values).
Second run 2026-11-29 at commit 4ab0879 (all 656 cases, in two chunks under nice on a
machine at load 4-5 on 2 cores): no internal error, no traceback, no NumPy warning, no file
written outside; 4 derives of the andrews squeezer ran past the 20 s guard in wall time
(20.3-21.0 s, in the symbolic adjugate). Exit 1 or 2 that did not name the parameter: an
overflow of the compiled blocks at the start and Newton's method completing the initial
values beside a parameter of extreme size; both name it since (:data:`EXTREME_FIXED`). Still
not naming it: the energy balance's budget refusal (it gives the projected evaluations) and
a kinetic energy refused as not positive definite (it names the speed and the eigenvalue).
"""

from __future__ import annotations

import json
import os
import random
import re
import signal
import sys
import time
import tomllib
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the hostile-input helpers, also when run as a script

from appell.examples import example_path  # noqa: E402
from appell.io.modelfile.expressions import FUNCTIONS  # noqa: E402
from test_modelfile_hostile import EDITS, EXPR_ALPHABET, INJECTIONS, _document, edit  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
#: bundled files added after the recorded full run (9b1fc31), left out so that each seed
#: keeps its case (FIXED below); the benchmark bicycle's derive and check alone take 40 s; the
#: driveshaft and the steering gear (issue 43) came after the second run
LATER = {"benchmark_bicycle.toml", "driveshaft.toml", "steering_gear.toml"}
EXAMPLES = sorted(p for p in example_path("pendulum").parent.glob("*.toml") if p.name not in LATER)
#: seeds of the default run and of the full run (APPELL_SLOW=1)
QUICK, FULL = 16, 2000
#: seconds one command may run before the hang guard stops it (not a speed measurement)
BOUND = 20.0
COMMANDS = ("derive", "check")

#: cases the first full run found outside the symbolic stages (issue 20), each fixed at its
#: root and kept here with a fragment of the output that shows the fix: seed -> (command,
#: exit code, fragment)
FIXED: dict[int, tuple[str, int, str]] = {
    # a potential (sin x + cos x + 1)^30: the energy balance's integration stops at its first
    # projection of the cost (numerics/budget.py), not after minutes (the first full run,
    # 2026-11-25, found 68 such cases)
    35: ("check", 1, "more than its budget of 50000 (stopped at t = "),
    # angular velocity nonlinear in the speeds: the 'power' identity does not hold, and the
    # balance is not formed (it failed the check with a residual of 0.3)
    250: ("check", 0, "not linear in the speeds"),
    # a velocity with (sin x + cos x + 1)^50 free of the speeds: decided without expanding
    1583: ("check", 0, "terms free of the speeds"),
    # a redundant leg written F^100 = 0 and F^3 = 0: a zero gradient where it holds (SVD
    # failure, then multipliers of 1e33 against the augmented route)
    432: ("check", 2, "the gradient of constraint 'leg_4' vanishes at the initial state"),
    494: ("check", 2, "the gradient of constraint 'leg_4' vanishes at the initial state"),
    # a swelling servo constraint: its closed-form solve for display is skipped over the bound
    740: ("derive", 0, "eigenvalues"),
    # a swelling first-integral candidate: not expanded over the bound
    798: ("check", 0, "passed"),
    # a kinetic energy with (sin x1 + cos x1 + 1)^30: the closed-loop tracking run stops at
    # its budget and is reported as not judged
    554: ("check", 0, "not judged: stopped at t = "),
    # a control law that is complex at a sampled state: named, not a TypeError
    832: ("check", 2, "is not a finite real number at t = "),
    # the second full run (2026-11-27): a Newton solve per evaluation, 1.5 ms each, ran past
    # the bound before the balance's seconds budget; since issue 19's session the balance ends
    # its span there with a note and compares what it integrated
    1807: ("check", 0, "where its integration had run 10 s"),
    # an energy of 1e-50 (a motion at rest): the balance failed on rounding
    1782: ("check", 0, "the energy balance holds"),
}

# ------------------------------------------------------------------------------ mutations
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*'*")
_WORDS = set(FUNCTIONS) | {"pi", "E", "t"}


def _leaves(node, path=()):
    """Paths of every entry of a parsed TOML document (tables, arrays and scalars)."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        yield path + (key,)
        yield from _leaves(value, path + (key,))


def _get(doc, path):
    for key in path:
        doc = doc[key]
    return doc


def _set(doc, path, value):
    parent = _get(doc, path[:-1])
    if value is _DELETE:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value


_DELETE = object()


#: entries that hold names or settings, not expressions
_NOT_EXPRESSIONS = {
    "kind",
    "name",
    "type",
    "parent",
    "child",
    "body",
    "rotation",
    "unit",
    "description",
    "method",
    "stabilization",
    "reactions",
}


def _expression_paths(doc) -> list[tuple]:
    """Paths of the expression strings of a parsed model file."""
    return [
        p
        for p in _leaves(doc)
        if isinstance(_get(doc, p), str)
        and _NAME.search(_get(doc, p))
        and p[0] not in ("model", "units", "simulation")
        and not set(map(str, p)) & _NOT_EXPRESSIONS
    ]


def _names(doc) -> list[str]:
    """The model's coordinates, parameters and the names its expressions use."""
    model, params = doc.get("model"), doc.get("parameters")
    found = set(model.get("coordinates", ()) if isinstance(model, dict) else ())
    found |= set(params if isinstance(params, dict) else ())
    for path in _expression_paths(doc):
        found |= {n for n in _NAME.findall(_get(doc, path)) if n.rstrip("'") not in _WORDS}
    return sorted(n for n in found if isinstance(n, str) and _NAME.fullmatch(n)) or ["x"]


def _expression(rng: random.Random, names, depth=0) -> str:
    """A random well-formed expression over ``names`` (functions of the reader)."""
    if depth > 3 or rng.random() < 0.3:
        return rng.choice([rng.choice(names), str(rng.randint(0, 9)), f"{rng.uniform(0, 10):.3g}", "pi"])
    kind = rng.random()
    if kind < 0.5:
        op = rng.choice(["+", "-", "*", "/", "^"])
        right = str(rng.randint(-4, 12)) if op == "^" else _expression(rng, names, depth + 1)
        return f"({_expression(rng, names, depth + 1)}){op}({right})"
    if kind < 0.6:
        return "-" + _expression(rng, names, depth + 1)
    name = rng.choice(sorted(FUNCTIONS))
    arity = 2 if FUNCTIONS[name][2] >= 2 else 1
    return f"{name}(" + ", ".join(_expression(rng, names, depth + 1) for _ in range(arity)) + ")"


def _swell(rng: random.Random, expr: str, names, coordinates) -> str:
    """``expr`` made to swell under expansion, simplification or differentiation (in a
    coordinate ``q`` where the model lists them)."""
    q = rng.choice(coordinates or names)
    n = rng.choice([7, 12, 30, 50, 100])
    kind = rng.randrange(6)
    if kind == 0:
        return f"({expr})^{rng.choice([3, 10, 30, 100])}"
    if kind == 1:
        return f"({expr}) + (sin({q}) + cos({q}) + 1)^{n}"
    if kind == 2:
        chain = q
        for _ in range(rng.randint(3, 12)):
            chain = f"{rng.choice(['exp', 'sin', 'cos'])}({chain})"
        return f"({expr})*{chain}"
    if kind == 3:
        sums = [f"({rng.choice(names)} + {k + 1})" for k in range(rng.randint(5, 40))]
        return f"({expr})*" + "*".join(sums)
    if kind == 4:
        return f"({expr})*(1 + {q}^2)^{n}"
    powers = " + ".join(f"{rng.choice(names)}^{k}" for k in range(1, rng.randint(4, 12)))
    return f"({expr})*({powers})^{n // 4 + 2}"


def _odd_value(rng: random.Random):
    return rng.choice(
        [
            0,
            -1,
            1e308,
            float("nan"),
            float("inf"),
            "",
            " ",
            True,
            [],
            {},
            [0, 0, 0],
            "x'''",
            "1/0",
            "0^0",
            10**30,
            -(10**30),
            "nan",
            "1e309",
        ]
    )


def mutate(seed: int) -> tuple[str, str, str]:
    """``(example name, what was done, mutated text)`` of case ``seed``."""
    rng = random.Random(seed)
    path = EXAMPLES[seed % len(EXAMPLES)]
    text = path.read_text(encoding="utf-8")
    kind = rng.choice(["text", "lines", "value", "swell", "swell"])
    if kind == "text":
        edits = []
        for _ in range(rng.randint(1, 4)):
            i = rng.randint(0, len(text))
            action, ch = rng.choice(EDITS), rng.choice(EXPR_ALPHABET)
            j = rng.randint(i, min(len(text), i + 40)) if action == "duplicate" else i
            text = edit(text, action, i, ch, j)
            edits.append(f"{action} {ch!r} at {i}" if action != "duplicate" else f"duplicate {i}:{j}")
        return path.stem, "text: " + "; ".join(edits), text
    if kind == "lines":
        lines, edits = text.splitlines(), []
        for _ in range(rng.randint(1, 3)):
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            action = rng.choice(["delete", "duplicate", "swap"])
            if action == "delete":
                del lines[i]
            elif action == "duplicate":
                lines.insert(j, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            edits.append(f"{action} line {i + 1}" + (f" to {j + 1}" if action != "delete" else ""))
        return path.stem, "lines: " + "; ".join(edits), "\n".join(lines) + "\n"
    doc = tomllib.loads(text)
    names = _names(doc)
    paths = list(_leaves(doc))
    if kind == "swell":
        exprs = _expression_paths(doc)
        if exprs:
            where = rng.choice(exprs)
            model = doc.get("model")
            coordinates = [
                c
                for c in (model.get("coordinates", ()) if isinstance(model, dict) else ())
                if isinstance(c, str) and _NAME.fullmatch(c)
            ]
            new = _swell(rng, _get(doc, where), names, coordinates)
            _set(doc, where, new)
            return path.stem, f"swell {'.'.join(map(str, where))} = {new!r}", _document(doc)
    where = rng.choice(paths)
    choice = rng.random()
    if choice < 0.45:
        value = _expression(rng, names)
    elif choice < 0.6:
        value = rng.choice(INJECTIONS)
    elif choice < 0.85:
        value = _odd_value(rng)
    else:
        value = _DELETE
    _set(doc, where, value)
    shown = "deleted" if value is _DELETE else repr(value)[:200]
    return path.stem, f"value {'.'.join(map(str, where))} = {shown}", _document(doc)


#: the extreme values each parameter takes in turn (issue 42): +-2^63, 1e-300, 1e300
EXTREMES = (2.0**63, -(2.0**63), 1e-300, 1e300)


def extreme_cases() -> list[tuple[Path, str, float]]:
    """``(model file, parameter, value)`` for every bundled model file, every parameter of its
    ``[parameters]`` table and every value of :data:`EXTREMES`."""
    cases = []
    for path in EXAMPLES:
        params = tomllib.loads(path.read_text(encoding="utf-8")).get("parameters", {})
        cases += [(path, name, value) for name in params for value in EXTREMES]
    return cases


def extreme_text(path: Path, name: str, value: float) -> str:
    """The model file ``path`` with the parameter ``name`` set to ``value``."""
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    entry = doc["parameters"][name]
    if isinstance(entry, dict):
        entry["value"] = value
    else:
        doc["parameters"][name] = value
    return _document(doc)


# ------------------------------------------------------------------------------ running
class Hang(BaseException):
    """Raised by the hang guard (not an Exception: no handler of appell catches it)."""


def _alarm(signum, frame):
    import traceback

    stack = traceback.extract_stack(frame)
    ours = [f"{Path(f.filename).name}:{f.lineno} {f.name}" for f in stack if "/appell/" in f.filename]
    raise Hang(" <- ".join(reversed(ours[-4:])) + f" (innermost: {Path(stack[-1].filename).name}:{stack[-1].lineno})")


#: the suite runs on several workers (pytest-xdist): other tests may then create entries in
#: the repository root while a case runs, so the root is listed only in a run of its own
PARALLEL = "PYTEST_XDIST_WORKER" in os.environ
#: caches that the libraries appell uses keep under HOME (not appell's writes)
LIBRARY_CACHES = (".cache/matplotlib", ".config/matplotlib", ".config/dask", ".cache/dask")


def _listing() -> dict:
    """Names (and modification times) of the places a run must not write to (compiled code
    goes to a cache inside the working folder, :func:`run_case`; HOME is a folder of the
    case's own, :func:`_home_writes`)."""
    places = [EXAMPLES[0].parent] + ([] if PARALLEL else [ROOT])
    out = {}
    for place in places:
        if place.is_dir():
            for entry in place.iterdir():
                try:
                    out[str(entry)] = entry.stat().st_mtime_ns if place == EXAMPLES[0].parent else 0
                except OSError:
                    pass
    return out


def _home_writes(home: Path) -> list[str]:
    """Files a run left in the case's HOME, but for the libraries' caches."""
    return sorted(
        str(p.relative_to(home))
        for p in home.rglob("*")
        if p.is_file() and not str(p.relative_to(home)).startswith(LIBRARY_CACHES)
    )


def run_command(command: str, path: Path, bound: float = BOUND) -> dict:
    """``{command, code, seconds, output, exception}`` of one in-process run under the guard."""
    from click.testing import CliRunner

    from appell.io.cli import cli

    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, bound)
    start = time.perf_counter()
    try:
        result = CliRunner().invoke(cli, [command, str(path)])
        code, output = result.exit_code, result.output
        exc = result.exception if not isinstance(result.exception, SystemExit) else None
        if exc is not None:
            import traceback

            output += "".join(traceback.format_exception(exc))
    except Hang as stopped:
        code, output, exc = None, f"stopped by the hang guard after {bound:g} s in {stopped}", "hang"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    return {
        "command": command,
        "code": code,
        "seconds": round(time.perf_counter() - start, 3),
        "output": output,
        "exception": None if exc is None else repr(exc),
    }


def violations(run: dict) -> list[str]:
    """The invariants ``run`` breaks (empty when it behaved)."""
    out, code = [], run["code"]
    text = run["output"]
    if code is None:
        out.append(f"hang: over {BOUND:g} s")
        return out
    if "internal error" in text or "a bug in appell" in text:
        out.append("internal error")
    if "Traceback (most recent call last)" in text or run["exception"]:
        out.append("traceback")
    if "RuntimeWarning" in text or "ComplexWarning" in text:
        out.append("a NumPy warning reached the user")
    if code not in (0, 1, 2):
        out.append(f"exit code {code}")
    elif code != 0 and not any(line.startswith("error:") for line in text.splitlines()):
        out.append(f"exit code {code} without an 'error:' line")
    return out


def run_case(seed: int, folder: Path, case_text: tuple[str, str, str] | None = None) -> dict:
    """Mutate, write into ``folder`` (also the working folder) and run every command
    (``case_text``: ``(example, what, text)`` in place of the mutation of ``seed``)."""
    name, what, text = mutate(seed) if case_text is None else case_text
    case = folder / f"case{seed}"
    case.mkdir()
    path = case / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    saved = {k: os.environ.get(k) for k in ("APPELL_CACHE_DIR", "HOME")}
    cwd, home = os.getcwd(), case / "home"
    home.mkdir()
    os.chdir(case)
    os.environ["APPELL_CACHE_DIR"] = str(case / "cache")
    os.environ["HOME"] = str(home)
    try:
        record = {"seed": seed, "example": name, "mutation": what, "runs": []}
        for command in COMMANDS:
            before = _listing()
            run = run_command(command, path)
            after = _listing()
            changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
            changed += [f"$HOME/{k}" for k in _home_writes(home)]
            run["violations"] = violations(run) + [f"wrote outside the working folder: {k}" for k in changed]
            record["runs"].append(run)
    finally:
        os.chdir(cwd)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    return record


def failures(record: dict) -> list[str]:
    return [
        f"seed {record['seed']} ({record['example']}, {record['mutation'][:300]}): {r['command']}: "
        f"{', '.join(r['violations'])}\n    " + r["output"][-1500:].replace("\n", "\n    ")
        for r in record["runs"]
        if r["violations"]
    ]


def _fuzz(seeds, folder: Path):
    found, start, seeds = [], time.perf_counter(), list(seeds)
    for seed in seeds:
        found.extend(failures(run_case(seed, folder)))
    print(
        f"{len(seeds)} cases, {len(seeds) * len(COMMANDS)} runs in {time.perf_counter() - start:.0f} s: "
        f"{len(found)} failing"
    )
    assert not found, f"{len(found)} failing run(s):\n" + "\n".join(found)


def test_mutations_are_seeded():
    assert mutate(7) == mutate(7)
    assert len({mutate(seed)[2] for seed in range(20)}) == 20


def test_quick_fuzz(tmp_path):
    _fuzz(range(QUICK), tmp_path)


@pytest.mark.parametrize("seed", sorted(FIXED))
def test_a_case_the_full_run_found_behaves(seed, tmp_path):
    """Each case of :data:`FIXED`: every command keeps the invariants, and the one named ends
    with the exit code and prints the fragment that shows the fix."""
    record = run_case(seed, tmp_path)
    assert not failures(record), "\n".join(failures(record))
    command, code, fragment = FIXED[seed]
    run = next(r for r in record["runs"] if r["command"] == command)
    assert run["code"] == code and fragment in run["output"], run["output"][-2000:]


@pytest.mark.slow
def test_full_fuzz(tmp_path):
    _fuzz(range(FULL), tmp_path)


def _extreme(indices, folder: Path):
    found, cases = [], extreme_cases()
    for k in indices:
        path, name, value = cases[k]
        record = run_case(
            100000 + k, folder, (path.stem, f"parameter {name} = {value!r}", extreme_text(path, name, value))
        )
        found.extend(failures(record))
    assert not found, f"{len(found)} failing run(s):\n" + "\n".join(found)


#: extreme-value cases of the default run: every value on the parameters of the pendulum
EXTREME_QUICK = ("pendulum",)

#: cases of the first extreme-value run (issue 42), each fixed at its root: (model, parameter,
#: value) -> (command, exit code, fragment of the output that shows the fix)
EXTREME_FIXED = {
    # the energy balance's error norms overflowed (NumPy warnings, then a failed step size)
    ("ball_on_tilting_plane", "g", 1e300): ("check", 1, "the parameter g = 1e+300 is of extreme size"),
    # the cross-check's augmented matrix singular to rounding: "internal error: LinAlgError" (the
    # servo cross-check's too: differential_drive, b = 1e-300, whose derive is slow for this run)
    ("pendulum", "L", 1e300): ("check", 1, "the parameter L = 1e+300 is of extreme size"),
    # a constraint row of 1e300: the norm in the vanishing-row test overflowed (a warning)
    ("cubic_acceleration", "c", 1e300): ("check", 0, "passed"),
    # second run (i42b): the model's blocks overflowed at the start, named without the culprit
    ("rolling_ball", "R", 1e300): ("check", 2, "R = 1e+300 is of extreme size beside the others"),
    # Newton's method completing the initial values drowned in rounding, named without the culprit
    ("pendulum", "L", 1e-300): ("check", 1, "the parameter L = 1e-300 is of extreme size beside the others"),
}


def test_extreme_parameter_values_quick(tmp_path):
    """Each parameter of the pendulum at +-2^63, 1e-300 and 1e300 in turn: no internal error,
    no traceback, no NumPy warning; a refusal names the culprit."""
    cases = extreme_cases()
    _extreme([k for k, (path, _, _) in enumerate(cases) if path.stem in EXTREME_QUICK], tmp_path)


@pytest.mark.parametrize("case", sorted(EXTREME_FIXED))
def test_an_extreme_case_the_run_found_behaves(case, tmp_path):
    example, name, value = case
    record = run_case(
        0, tmp_path, (example, f"parameter {name} = {value!r}", extreme_text(example_path(example), name, value))
    )
    assert not failures(record), "\n".join(failures(record))
    command, code, fragment = EXTREME_FIXED[case]
    run = next(r for r in record["runs"] if r["command"] == command)
    assert run["code"] == code and fragment in run["output"], run["output"][-2000:]


def test_a_failed_cross_check_names_the_parameter_of_extreme_size():
    """A cross-check that fails beside a parameter of extreme size says so in the line that
    ``appell check`` ends with (it said only "cross-check: a relative difference exceeds
    1e-09"): the servo route of differential_drive at m = 2^63 (the augmented system and the
    split differ by 100 % in the accelerations there) and the plain route of the door on two
    hinges at g = 1e-300 (its reactions of 1e-299 lose their minimum-norm split to underflow).
    At ordinary values both pass: the clause is not there."""
    from appell.control.servo_numeric import cross_check_controlled
    from appell.numerics.crosscheck import cross_check
    from appell.workflows import load_derivation, verdict

    drive = load_derivation("differential_drive")
    door = load_derivation("door_two_hinges")
    for report, clause in (
        (cross_check_controlled(drive, p={"m": 2.0**63}), "the parameter m = 9.22e+18"),
        (cross_check(door, p={"g": 1e-300}), "the parameter g = 1e-300"),
    ):
        ok, line = verdict(report, None, 1e-9, 1e-9)
        assert not ok and f"{clause} is of extreme size beside the others" in line, line
        assert "rescale the model's units" in line
    for report in (cross_check_controlled(drive), cross_check(door)):
        ok, line = verdict(report, None, 1e-9, 1e-9)
        assert ok and "extreme" not in line, line


@pytest.mark.slow
def test_extreme_parameter_values_full(tmp_path):
    _extreme(range(len(extreme_cases())), tmp_path)


if __name__ == "__main__":  # python tests/test_fuzz.py START STOP results.jsonl [extreme]
    import tempfile

    start, stop, out = int(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])
    extreme = sys.argv[4:] == ["extreme"]
    with tempfile.TemporaryDirectory() as tmp, out.open("a", encoding="utf-8") as sink:
        for seed in range(start, min(stop, len(extreme_cases())) if extreme else stop):
            if extreme:
                path, name, value = extreme_cases()[seed]
                record = run_case(
                    100000 + seed,
                    Path(tmp),
                    (path.stem, f"parameter {name} = {value!r}", extreme_text(path, name, value)),
                )
            else:
                record = run_case(seed, Path(tmp))
            for run in record["runs"]:
                run["output"] = run["output"][-3000:]
            sink.write(json.dumps(record) + "\n")
            sink.flush()
