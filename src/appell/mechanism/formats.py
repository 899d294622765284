"""The file formats of mechanisms that appell reads besides its own model files: one entry
per format, which the loader (:func:`appell.load_model`), the command line and the
``[mechanism]`` table of a model file all consult, so that a new format is one entry here.

Each :class:`Importer` names the format, the suffixes of its files, what reads a file into a
:class:`~appell.model.System`, whether a floating base may be asked for, and the extra that
installs what it needs. Readers are imported when a file is read, so that a format whose
package is missing costs nothing until it is used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Importer", "IMPORTERS", "importer_for", "suffixes", "described"]


def _urdf_system(path: Path, floating_base: bool):
    from appell.mechanism.urdf import urdf_system

    return urdf_system(path, floating_base=floating_base)


def _urdf_mechanism(path: Path, floating_base: bool):
    from appell.mechanism.urdf import read_urdf, urdf_mechanism

    return urdf_mechanism(read_urdf(path), floating_base=floating_base)


def _mjcf_system(path: Path, floating_base: bool, **options):
    from appell.mechanism.mjcf import mjcf_system

    return mjcf_system(path, **options)


def _sdf_system(path: Path, floating_base: bool):
    from appell.mechanism.sdf import sdf_system

    return sdf_system(path)


@dataclass(frozen=True)
class Importer:
    """A file format: ``name``, ``suffixes`` (lower case, with the dot), ``what`` its files
    hold (for messages), ``system(path, floating_base)`` the reader, ``mechanism(path,
    floating_base)`` -> ``(Mechanism, extra constraints)`` where a model file's ``[mechanism]``
    table may add to it under the key ``key`` (None: not available there), whether
    ``floating_base`` applies, the pip extra that brings its reader's package, and the
    ``options`` its ``system`` reader takes by name (text values; ``appell ... --mjcf``)."""

    name: str
    suffixes: tuple[str, ...]
    what: str
    system: Callable
    mechanism: Callable | None = None
    key: str | None = None
    floating_base: bool = False
    extra: str | None = None
    options: tuple[str, ...] = ()


IMPORTERS: tuple[Importer, ...] = (
    Importer("URDF", (".urdf",), "a robot description", _urdf_system, _urdf_mechanism, key="urdf", floating_base=True),
    Importer(
        "MJCF",
        (".xml", ".mjcf"),
        "a MuJoCo model",
        _mjcf_system,
        extra="mjcf",
        options=("frictionloss", "armature", "actuators"),
    ),
    Importer("SDF", (".sdf",), "an SDFormat model", _sdf_system),
)


def importer_for(path) -> Importer | None:
    """The importer of ``path`` by its suffix (any case); None for a model file (``.toml``)
    or an unknown suffix."""
    suffix = Path(path).suffix.lower()
    return next((imp for imp in IMPORTERS if suffix in imp.suffixes), None)


def suffixes() -> tuple[str, ...]:
    """Every suffix an importer reads."""
    return tuple(s for imp in IMPORTERS for s in imp.suffixes)


def described() -> str:
    """``"a model file (.toml), a robot description (.urdf), a MuJoCo model (.xml, .mjcf) or an
    SDFormat model (.sdf)"``
    for messages and help."""
    parts = ["a model file (.toml)"] + [f"{imp.what} ({', '.join(imp.suffixes)})" for imp in IMPORTERS]
    return ", ".join(parts[:-1]) + " or " + parts[-1]
