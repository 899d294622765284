"""Bundled examples: Python builders (:mod:`.catalog`) and model files in this folder."""

from .catalog import CATALOG, car, chaplygin_sleigh, cone_particle, cubic_acceleration, knife_edge, pendulum, rolling_ball

from pathlib import Path as _Path


def list_examples() -> list[str]:
    """Names of the bundled model files (``<name>.toml`` in this folder), sorted."""
    return sorted(p.stem for p in _Path(__file__).parent.glob("*.toml"))


def example_path(name: str) -> _Path:
    """Path of the bundled model file ``<name>.toml``; :class:`~appell.errors.ModelError` if none."""
    path = _Path(__file__).parent / f"{name}.toml"
    if not path.is_file():
        from ..errors import ModelError

        raise ModelError(f"no bundled example {name!r}", hint="examples: " + ", ".join(list_examples()))
    return path


__all__ = ["CATALOG", "car", "chaplygin_sleigh", "cone_particle", "cubic_acceleration", "example_path", "knife_edge",
           "list_examples", "pendulum", "rolling_ball"]
