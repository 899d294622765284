"""The plain parts of a compiled MuJoCo model (``mujoco.MjModel``), without SymPy: loading a
file (:func:`load_mjcf`), the names appell gives MJCF elements (:class:`_Names`), the
coordinates each joint kind adds (:data:`_DERIVED`), MuJoCo's quaternions as rotations, and the
compiled model's flags and names (:func:`_flag`, :func:`_names`). Shared by the symbolic reader
(:mod:`appell.mechanism.mjcf`) and the floating-point joint tree (:mod:`appell.mechanism.mjcf_tree`).
"""

from __future__ import annotations

import keyword
import re
from pathlib import Path

import numpy as np

from appell.errors import ModelError, import_optional
from appell.names import name_problem

__all__ = ["load_mjcf"]


def _mujoco():
    """The mujoco package, or :class:`~appell.errors.MissingDependencyError` naming the extra
    (``pip install 'appell[mjcf]'``)."""
    return import_optional("mujoco", extra="mjcf", feature="reading a MuJoCo model (MJCF)")


def _rotation(quat) -> np.ndarray:
    w, x, y, z = (float(v) for v in quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _names(model, kind, count) -> list[str | None]:
    mujoco = _mujoco()
    return [mujoco.mj_id2name(model, kind, i) for i in range(count)]


class _Names:
    """MJCF names (per element kind, any characters) -> appell identifiers (one namespace):
    characters that are not ASCII letters, digits or ``_`` become ``_`` (no ``__``), a name
    that does not start with a letter, or is reserved, gets its kind before it
    (``2XL430`` -> ``class_2XL430``), and a name already taken by another kind gets the kind
    as a suffix (``waistRoll`` the joint, ``waistRoll_body`` the body). ``table`` keeps
    ``identifier -> (kind, MJCF name)`` for every name that changed."""

    def __init__(self, reserved=()):
        self.used = set(reserved)
        self.table: dict[str, tuple[str, str]] = {}
        self.kept: list[str] = []  # the names that are MuJoCo's own

    def claim(self, kind: str, original: str | None, fallback: str, derived=()) -> str:
        base = original or fallback
        ident = re.sub(r"_+", "_", re.sub(r"\W", "_", base, flags=re.ASCII)).strip("_")[:48]
        if not ident or not ident[0].isalpha() or keyword.iskeyword(ident) or name_problem(ident):
            ident = f"{kind}_{ident}".rstrip("_")
        candidate, k = ident, 1
        while candidate in self.used or any(candidate + d in self.used for d in derived):
            candidate = f"{ident}_{kind}" if k == 1 else f"{ident}_{kind}{k}"
            k += 1
        self.used.add(candidate)
        self.used.update(candidate + d for d in derived)
        if original and candidate != original:
            self.table[candidate] = (kind, original)
        elif original:
            self.kept.append(candidate)
        return candidate

    def shown(self, ident: str) -> str:
        """``ident`` as the file spells it (for messages: the note gives the identifier)."""
        kind, original = self.table.get(ident, (None, None))
        return repr(ident) if original is None else repr(original)


#: the coordinates and constraints a joint of each kind adds beside its name
_DERIVED = {
    "free": ("_x", "_y", "_z", "_q0", "_q1", "_q2", "_q3", "_unit"),
    "ball": ("_q0", "_q1", "_q2", "_q3", "_unit"),
    "hinge": (),
    "slide": (),
}


def _joint_kinds(mujoco) -> dict[int, str]:
    """MuJoCo's joint types -> ``hinge``, ``slide``, ``ball``, ``free``."""
    return {
        int(mujoco.mjtJoint.mjJNT_HINGE): "hinge",
        int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
        int(mujoco.mjtJoint.mjJNT_BALL): "ball",
        int(mujoco.mjtJoint.mjJNT_FREE): "free",
    }


def _mapping_notes(merged, names: _Names) -> list[str]:
    """The note's items of a reading: the massless bodies merged, the names mapped."""
    out = []
    if merged:
        out.append(f"massless bodies merged into their parents: {', '.join(merged)}")
    if names.table:
        out.append(
            "names mapped to identifiers: "
            + ", ".join(f"{kind} {orig!r} -> {ident}" for ident, (kind, orig) in names.table.items())
        )
    return out


def _flag(model, name: str) -> bool:
    """Whether MuJoCo's ``disableflags`` has ``mjDSBL_<name>`` set (False where this MuJoCo has no such flag)."""
    mujoco = _mujoco()
    bit = getattr(mujoco.mjtDisableBit, f"mjDSBL_{name}", None)
    return bit is not None and bool(int(model.opt.disableflags) & int(bit))


def load_mjcf(source) -> object:
    """The compiled ``mujoco.MjModel`` of a file path or an XML string; MuJoCo's own error
    message (file and line where it gives them) as a :class:`ModelError`."""
    mujoco = _mujoco()
    text = str(source)
    try:
        if text.lstrip().startswith("<"):
            return mujoco.MjModel.from_xml_string(text)
        path = Path(source)
        if not path.is_file():
            raise ModelError(f"{path}: no such MuJoCo model file")
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelError(
            f"MuJoCo could not read the model: {str(exc).strip()}",
            where=None if text.lstrip().startswith("<") else str(source),
            hint="check the file with MuJoCo's own tools (python -m mujoco.viewer)",
        ) from exc


#: what has no meaning for the rigid-body motion appell computes, each with what tells it
_IGNORED = (
    ("contacts between geoms", lambda m: m.ngeom and np.any((m.geom_contype != 0) | (m.geom_conaffinity != 0))),
    ("joint limits", lambda m: np.any(np.asarray(m.jnt_limited) != 0)),
    ("tendon limits", lambda m: m.ntendon and np.any(np.asarray(m.tendon_limited) != 0)),
    ("soft-constraint parameters (solref, solimp) of the equalities (held rigid here)", lambda m: m.neq),
    ("sensors", lambda m: m.nsensor),
    ("cameras, lights and visual settings", lambda m: m.ncam or m.nlight),
    ("keyframes", lambda m: m.nkey),
    (
        "fluid forces (density, viscosity, wind)",
        lambda m: float(m.opt.density) != 0 or float(m.opt.viscosity) != 0 or np.any(np.asarray(m.opt.wind) != 0),
    ),
)
