"""The multibody front end: bodies, frames and joints in; an :class:`appell.System` with
joint reactions (forces and moments) as outputs (docs/mechanism.md).

Model level: imports only :mod:`appell.model`, :mod:`appell.errors`, :mod:`appell.symbols`.
"""

import importlib

#: where each name of the package is defined: imported on first use (PEP 562), so that reading
#: a robot file (:mod:`appell.mechanism.urdf`) needs no SymPy
_WHERE = {
    **dict.fromkeys(("GROUND", "Body", "Frame", "Joint", "Mechanism"), "appell.mechanism.builder"),
    **dict.fromkeys(("KINDS", "JointMotion", "joint_motion"), "appell.mechanism.joints"),
}

__all__ = ["GROUND", "Body", "Frame", "Joint", "JointMotion", "KINDS", "Mechanism", "joint_motion", "rotations"]


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    try:
        return importlib.import_module(f"{__name__}.{name}")  # a submodule (rotations, urdf, ...)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":
            raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
