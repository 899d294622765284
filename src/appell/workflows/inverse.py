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


def closed_chain_model(system, reasons: list | None = None):
    """The :class:`~appell.numerics.loops.LoopModel` of a mechanism's
    :class:`~appell.model.System` whose tree is closed by holonomic constraints (loop
    closures: ``connect`` in a ``[[closures]]`` table, an MJCF equality), through which
    :func:`run_inverse` completes the passive coordinates from the given ones; None for a
    system without a joint tree or constraints, or one the closed-chain route does not take
    (loads, servo constraints, its own energies: :func:`~appell.numerics.loops.loop_model`
    says which, appended to ``reasons``), whose motion is then given whole (``--drive``
    naming the drives)."""
    if getattr(system, "tree", None) is None or not system.constraints:
        return None
    from appell.numerics.loops import loop_model

    try:
        return loop_model(system)
    except ModelError as exc:
        if reasons is not None:
            reasons.append(exc.message)
        return None


def load_inverse_source(
    model: str,
    overrides=None,
    floating_base: bool = False,
    cache: bool | None = None,
    reactions_in: str | None = None,
    reader=None,
    echo=None,
    contacts=(),
):
    """What ``appell inverse`` works on: the :func:`closed_chain_model` of a closed chain (no
    derivation: the tree's recursions and the loops' rows), else the derivation
    (:func:`load_derivation`), with a note saying why where the closed-chain route refused a
    model with constraints. ``contacts`` (``appell inverse --contact``: ``NAME``,
    ``NAME:point``, ``NAME:weld``; a body, or an MJCF body or site by its MJCF name) are
    added as loop rows to the world (:func:`appell.simulation.inverse.contact_model`), refused
    with the reason where the closed-chain route does not take the model. The model's notes
    are printed once."""
    echo = echo or _print
    notes, reasons = [], []
    system = load_system(
        model,
        overrides,
        floating_base,
        echo=lambda text, err=False: notes.append(text),
        reactions_in=reactions_in,
        reader=reader,
    )
    if contacts:
        from appell.mechanism.formats import importer_for
        from appell.simulation.inverse import contact_model

        points = None
        if getattr(importer_for(Path(model)), "name", None) == "MJCF":
            from appell.mechanism.mjcf import mjcf_points

            points = mjcf_points(Path(model))
        try:
            closed = contact_model(system, list(contacts), points)
        except ModelError as exc:
            raise ModelError(f"--contact: {exc.message}", where=str(model), hint=exc.hint) from None
    else:
        closed = closed_chain_model(system, reasons)
    if closed is not None:  # the file's own spelling, for run_inverse (a contact's name from its body or site)
        closed.names = {
            **dict(system.names),
            **{
                c.name.removesuffix("_contact"): c.body
                for c, *_ in getattr(closed, "contacts", ())
                if not c.body.isidentifier()
            },
        }
    if closed is None:
        for reason in reasons:
            echo(
                f"note: the closed-chain route, which completes the passive coordinates from the given ones, "
                f"does not take this model: {reason}; the motion must give every coordinate",
                err=True,
            )
        return load_derivation(
            model, overrides, floating_base, cache=cache, reactions_in=reactions_in, reader=reader, echo=echo
        )
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
        raise ModelError(
            f"{trajectory}: the motion needs a column t and one per given coordinate",
            hint="columns: t and the actuated (or other independent) coordinates among " + ", ".join(names),
        )
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
        raise ModelError(
            f"--guess of unknown coordinate(s) {', '.join(unknown)}", hint="coordinates: " + ", ".join(names)
        )
    try:
        result = inverse_dynamics(
            model, table["t"], {n: table[n] for n in given}, w, a, drives=list(drives) or None, guess=values or None
        )
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
    assembly), and the output holds every drive, loop force and joint wrench. A model whose
    file's names are not identifiers (``System.names``: MJCF's ``left-hip-roll``) takes them
    in the file, ``--drive`` and ``--guess`` and shows them in the output and messages."""
    from appell.names import given_names, shown_names

    echo = echo or _print
    table = read_trajectory(Path(trajectory)) if table is None else table
    names = dict(
        getattr(derivation, "names", {})
        if hasattr(derivation, "loop_rows")  # load_inverse_source's
        else getattr(getattr(derivation, "system", None), "names", ())
    )
    if not names:
        return _run_inverse(derivation, trajectory, drives, out, echo, table, guess)
    # a file whose names are not identifiers (MJCF's 'left-hip-roll'): read and shown as it spells them

    def shown(text, **kw):
        return echo(shown_names([text], names)[0], **kw)

    table = dict(zip(given_names(table, names), table.values()))
    drives = given_names(drives, names)
    guess = dict(zip(given_names(guess, names), guess.values())) if guess else guess
    try:
        return _run_inverse(derivation, trajectory, drives, out, shown, table, guess, names)
    except (ModelError, ComputationError) as exc:
        raise type(exc)(
            shown_names([exc.message], names)[0], where=exc.where, hint=exc.hint and shown_names([exc.hint], names)[0]
        ) from None


def _run_inverse(derivation, trajectory, drives, out, echo, table, guess, names=None):
    """:func:`run_inverse` on the table read (the model's identifiers); ``names`` as shown."""
    import numpy as np

    from appell.numerics.boundary import numeric_model
    from appell.simulation.inverse import inverse_dynamics
    from appell.simulation.recording import acceleration_name

    if hasattr(derivation, "loop_rows"):  # a closed chain's LoopModel (load_inverse_source)
        result, given = _closed_chain_inverse(derivation, trajectory, table, drives, guess, echo)
        return _write_inverse(result, derivation.name, out, given, echo, names)
    if guess:
        raise ModelError(
            "--guess applies to a closed chain (a mechanism whose loops the motion completes)",
            hint="this model's motion gives every coordinate; leave --guess out",
        )
    numeric = numeric_model(derivation)
    missing = [n for n in ("t",) + tuple(numeric.coordinate_names) if n not in table]
    if missing:
        closed = getattr(getattr(derivation.system, "tree", None), "loops", ())
        raise ModelError(
            f"{trajectory}: no column {', '.join(missing)}",
            hint="columns: t and the coordinates "
            + ", ".join(numeric.coordinate_names)
            + (
                "; the closed-chain route, which completes the passive ones from the loops, does not "
                "take this model (the note above says why)"
                if closed
                else ""
            ),
        )
    q = np.stack([table[n] for n in numeric.coordinate_names], axis=1)

    def given(names):
        return np.stack([table[n] for n in names], 1) if all(n in table for n in names) else None

    w = given(numeric.speed_names)
    a = given([acceleration_name(n) for n in numeric.speed_names]) if w is not None else None
    result = inverse_dynamics(derivation, table["t"], q, w, a, drives=list(drives) or None)
    return _write_inverse(result, derivation.system.name, out, w is not None, echo, names)


def _write_inverse(result, name, out, given, echo, names=None):
    """``result`` written to ``out`` (default ``<name>-inverse.csv``; the columns named as the
    model's file spells them, ``names``), its summary on ``echo``."""
    import numpy as np

    path = Path(out) if out is not None else default_file_name(name, "-inverse.csv")
    output_target(path)
    result.to_csv(path, names)
    for drive, values in result.drives.items():
        k = int(np.argmax(np.abs(values)))
        echo(f"drive_{drive}: largest |value| {abs(values[k]):.6g} at t = {result.t[k]:.6g}")
    if result.multipliers:
        echo(f"largest velocity-level residual of the given motion: {result.residual:.3e}")
    echo(f"{'given' if given else 'derived'} speeds and accelerations; {result.t.size} rows")
    echo(f"wrote {path}")
    return result
