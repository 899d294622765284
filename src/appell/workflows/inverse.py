"""``appell inverse``: the drives and reactions along a given motion (:func:`run_inverse`), of a
closed chain through its loops (:func:`load_inverse_source`, :func:`closed_chain_model`).
"""

from __future__ import annotations

from pathlib import Path

from appell.errors import ComputationError, ModelError
from appell.files import default_file_name, output_target
from appell.workflows.load import _print, load_derivation, load_system


def read_trajectory(path: Path) -> dict:
    """The columns (NumPy arrays) of a CSV file of numbers with a header row, by name."""
    import csv

    import numpy as np

    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read the trajectory: {exc}", where=str(path)) from None
    if len(rows) < 2:
        raise ModelError("the trajectory needs a header row and at least one row of numbers", where=str(path))
    header = [h.strip() for h in rows[0]]
    columns: dict[str, list[float]] = {h: [] for h in header}
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise ModelError(f"{len(row)} values for {len(header)} columns", where=f"{path}:{line}")
        for h, cell in zip(header, row):
            try:
                value = float(cell)
            except ValueError:
                raise ModelError(f"column {h!r}: {cell!r} is not a number", where=f"{path}:{line}") from None
            if not np.isfinite(value):
                raise ModelError(f"column {h!r}: {cell!r} is not a finite number", where=f"{path}:{line}")
            columns[h].append(value)
    return {h: np.array(v) for h, v in columns.items()}


def closed_chain_model(system):
    """The :class:`~appell.numerics.loops.LoopModel` of a mechanism's
    :class:`~appell.model.System` whose tree is closed by holonomic constraints (loop
    closures: ``connect`` in a ``[[closures]]`` table, an MJCF equality), through which
    :func:`run_inverse` completes the passive coordinates from the given ones; None for a
    system without a joint tree or constraints, or one the closed-chain route does not take
    (loads, servo constraints, its own energies: :func:`~appell.numerics.loops.loop_model`
    says which), whose motion is then given whole (``--drive`` naming the drives)."""
    if getattr(system, "tree", None) is None or not system.constraints:
        return None
    from appell.numerics.loops import loop_model

    try:
        return loop_model(system)
    except ModelError:
        return None


def load_inverse_source(model: str, overrides=None, floating_base: bool = False, cache: bool | None = None,
                        reactions_in: str | None = None, reader=None, echo=None):
    """What ``appell inverse`` works on: the :func:`closed_chain_model` of a closed chain (no
    derivation: the tree's recursions and the loops' rows), else the derivation
    (:func:`load_derivation`). The model's notes are printed once."""
    echo = echo or _print
    notes = []
    system = load_system(model, overrides, floating_base, echo=lambda text, err=False: notes.append(text),
                         reactions_in=reactions_in, reader=reader)
    closed = closed_chain_model(system)
    if closed is None:
        return load_derivation(model, overrides, floating_base, cache=cache, reactions_in=reactions_in,
                               reader=reader, echo=echo)
    for text in notes:
        echo(text, err=True)
    return closed


def _closed_chain_inverse(model, trajectory, table, drives, guess, echo):
    """:func:`run_inverse` of a closed chain (its :class:`~appell.numerics.loops.LoopModel`):
    the motion of the coordinates the file gives (any independent set: the actuated ones),
    the passive ones completed from the loops by
    :func:`appell.simulation.inverse.inverse_dynamics`; a motion the drives cannot produce, or
    that leaves the loops open, is bad input (:class:`ModelError`) naming the file."""
    from appell.simulation.inverse import inverse_dynamics
    from appell.simulation.recording import acceleration_name

    names, speeds = list(model.coordinate_names), list(model.speed_names)
    given = [n for n in names if n in table]
    if "t" not in table or not given:
        raise ModelError(f"{trajectory}: the motion needs a column t and one per given coordinate",
                         hint="columns: t and the actuated (or other independent) coordinates among "
                              + ", ".join(names))
    rates = [speeds[names.index(n)] for n in given]

    def column(names_):
        return {n: table[n] for n in names_} if all(n in table for n in names_) else None

    w = column(rates)
    a = column([acceleration_name(n) for n in rates]) if w is not None else None
    if a is not None:
        a = {r: a[acceleration_name(r)] for r in rates}
    try:
        values = {str(k): float(v) for k, v in dict(guess or {}).items()}
    except ValueError as exc:
        raise ModelError(f"--guess: {exc}", hint="give NAME=NUMBER, a passive coordinate's start") from None
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise ModelError(f"--guess of unknown coordinate(s) {', '.join(unknown)}", hint="coordinates: " + ", ".join(names))
    try:
        result = inverse_dynamics(model, table["t"], {n: table[n] for n in given}, w, a,
                                  drives=list(drives) or None, guess=values or None)
    except ComputationError as exc:  # the motion given cannot be followed: the file's fault, not appell's
        raise ModelError(exc.message, where=str(trajectory), hint=exc.hint) from None
    passive = [n for n in names if n not in given]
    echo(f"given {', '.join(given)}; completed from the loops: {', '.join(passive) or 'none'}")
    for comb in result.undetermined:
        echo("undetermined (minimum-norm answer given): " + " + ".join(f"{v:.6g}*{k}" for k, v in comb.items()))
    if result.undetermined_wrenches:
        echo("joint wrenches those change: " + ", ".join(result.undetermined_wrenches))
    return result, w is not None


def run_inverse(derivation, trajectory, drives=(), out=None, echo=None, table=None, guess=None):
    """``appell inverse``: :func:`appell.simulation.inverse.inverse_dynamics` along the motion
    of the CSV file ``trajectory`` (:func:`read_trajectory`: t and each coordinate; speeds and
    accelerations where given; ``table``: its columns read already), written to ``out``
    (default ``<model name>-inverse.csv``). ``derivation`` may be the
    :class:`~appell.numerics.loops.LoopModel` of a closed chain (:func:`load_inverse_source`): the file
    then gives the independent coordinates alone (the actuated ones), the passive ones are
    completed from the loops (``guess``: ``{coordinate: start}`` for the first time's
    assembly), and the output holds every drive, loop force and joint wrench."""
    import numpy as np

    from appell.numerics.boundary import numeric_model
    from appell.simulation.inverse import inverse_dynamics
    from appell.simulation.recording import acceleration_name

    echo = echo or _print
    table = read_trajectory(Path(trajectory)) if table is None else table
    if hasattr(derivation, "loop_rows"):  # a closed chain's LoopModel (load_inverse_source)
        result, given = _closed_chain_inverse(derivation, trajectory, table, drives, guess, echo)
        return _write_inverse(result, derivation.name, out, given, echo)
    if guess:
        raise ModelError("--guess applies to a closed chain (a mechanism whose loops the motion completes)",
                         hint="this model's motion gives every coordinate; leave --guess out")
    numeric = numeric_model(derivation)
    missing = [n for n in ("t",) + tuple(numeric.coordinate_names) if n not in table]
    if missing:
        raise ModelError(f"{trajectory}: no column {', '.join(missing)}",
                         hint="columns: t and the coordinates " + ", ".join(numeric.coordinate_names))
    q = np.stack([table[n] for n in numeric.coordinate_names], axis=1)

    def given(names):
        return np.stack([table[n] for n in names], 1) if all(n in table for n in names) else None

    w = given(numeric.speed_names)
    a = given([acceleration_name(n) for n in numeric.speed_names]) if w is not None else None
    result = inverse_dynamics(derivation, table["t"], q, w, a, drives=list(drives) or None)
    return _write_inverse(result, derivation.system.name, out, w is not None, echo)


def _write_inverse(result, name, out, given, echo):
    """``result`` written to ``out`` (default ``<name>-inverse.csv``), its summary on ``echo``."""
    import numpy as np

    path = Path(out) if out is not None else default_file_name(name, "-inverse.csv")
    output_target(path)
    result.to_csv(path)
    for drive, values in result.drives.items():
        k = int(np.argmax(np.abs(values)))
        echo(f"drive_{drive}: largest |value| {abs(values[k]):.6g} at t = {result.t[k]:.6g}")
    if result.multipliers:
        echo(f"largest velocity-level residual of the given motion: {result.residual:.3e}")
    echo(f"{'given' if given else 'derived'} speeds and accelerations; {result.t.size} rows")
    echo(f"wrote {path}")
    return result
