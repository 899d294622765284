"""``appell stability``: eigenvalues against a parameter (:func:`stability_analysis`, the model's
``[stability]`` table) and their files (:func:`write_stability`).
"""

from __future__ import annotations

import json
from pathlib import Path

from appell.files import atomic_path


def stability_table(system) -> dict:
    """The model file's [stability] table (``{}`` without one)."""
    return dict(dict(system.settings).get("stability", ()))


def stability_analysis(derivation, spec=None, free=(), ignore=()):
    """:func:`appell.numerics.stability.stability_sweep` as ``appell stability`` runs it:
    ``spec`` ``NAME=START:STOP:NUM``, ``free`` and ``ignore`` names (``('cyclic',)``), each
    defaulting to the model's [stability] table; the point is the model's initial values
    (those written in a varied parameter follow it). None when neither ``spec`` nor a
    table is given."""
    from appell.numerics.stability import stability_sweep
    from appell.simulation.sweep import parse_spec
    from appell.symbols import canonical_name

    table = stability_table(derivation.system)
    spec = spec if spec is not None else table.get("vary")
    if spec is None:
        return None
    free = tuple(free) or tuple(table.get("free", ()))
    ignore = tuple(ignore) or (("cyclic",) if table.get("ignore") == "cyclic" else tuple(table.get("ignore", ())))
    name, values = parse_spec(spec)
    name = canonical_name(name)
    ignored = "cyclic" if ignore == ("cyclic",) else tuple(canonical_name(i) for i in ignore) or None
    return stability_sweep(
        derivation, name, values, free=tuple(canonical_name(f) for f in free), ignore=ignored, progress=None
    )


def write_stability(result, path: Path) -> None:
    """The sweep as JSON, CSV, netCDF or a plot, written atomically."""
    from appell.files import write_bytes

    kind = path.suffix.lower()
    if kind in (".png", ".svg", ".pdf"):
        result.plot(path)
        return
    if kind == ".nc":
        data = result.to_xarray().to_netcdf(engine="h5netcdf")
    elif kind == ".json":
        data = json.dumps(
            {
                "name": result.name,
                "values": result.values.tolist(),
                "states": list(result.states),
                "modes": list(result.names),
                "real": result.eigenvalues.real.tolist(),
                "imag": result.eigenvalues.imag.tolist(),
                "crossings": [
                    {
                        "mode": c.mode,
                        "value": c.value,
                        "imag": c.imag,
                        "kind": c.kind,
                        "becomes": "unstable" if c.direction > 0 else "stable",
                    }
                    for c in result.crossings
                ],
            },
            indent=1,
        ).encode()
    else:
        m = result.eigenvalues.shape[1]
        head = ",".join([result.name] + [f"real_{j},imag_{j}" for j in range(m)])
        rows = [
            ",".join([repr(float(v))] + [f"{float(e.real)!r},{float(e.imag)!r}" for e in row])
            for v, row in zip(result.values, result.eigenvalues)
        ]
        data = ("\n".join([head] + rows) + "\n").encode()
    with atomic_path(path) as tmp:
        write_bytes(tmp, data)
