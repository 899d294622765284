"""Bundled examples: Python builders (:mod:`.catalog`) and model files in this folder.

The builders (SymPy) are imported on first use of their names (:data:`BUILDERS`, :data:`CATALOG`,
``pendulum``, ...): listing and locating the model files (``appell examples``) needs none."""

from pathlib import Path as _Path

#: the builders of :mod:`.catalog`, imported on first use
_CATALOG_NAMES = (
    "CATALOG",
    "car",
    "chaplygin_sleigh",
    "cone_particle",
    "cubic_acceleration",
    "knife_edge",
    "pendulum",
    "rolling_ball",
)


def __getattr__(name):
    if name in _CATALOG_NAMES:
        from . import catalog

        return getattr(catalog, name)
    if name == "BUILDERS":  # name of each bundled <name>.toml -> the Python builder of the same system
        global BUILDERS
        BUILDERS = _builders()
        return BUILDERS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _builders() -> dict:
    """name -> builder (a callable returning the System) for every bundled model file."""
    from .benchmark_examples import BENCHMARK_EXAMPLES
    from .catalog import CATALOG
    from .cyclic_examples import (
        spherical_pendulum,
        spherical_pendulum_cartesian,
        spherical_pendulum_rod,
        symmetric_top,
        turntable_particle,
    )
    from .drive_examples import DRIVE_EXAMPLES
    from .event_examples import EVENT_EXAMPLES
    from .machine_examples import driveshaft, steering_gear
    from .mechanism_examples import benchmark_bicycle, four_bar, rolling_disc
    from .servo_examples import SERVO_EXAMPLES
    from .support_examples import SUPPORT_EXAMPLES

    cyclic = (
        spherical_pendulum,
        spherical_pendulum_rod,
        spherical_pendulum_cartesian,
        symmetric_top,
        turntable_particle,
    )
    return {
        **CATALOG,
        **SERVO_EXAMPLES,
        **{f.__name__: f for f in cyclic},
        **EVENT_EXAMPLES,
        **BENCHMARK_EXAMPLES,
        **DRIVE_EXAMPLES,
        **SUPPORT_EXAMPLES,
        "four_bar": four_bar,
        "rolling_disc": rolling_disc,
        "benchmark_bicycle": benchmark_bicycle,
        "driveshaft": driveshaft,
        "steering_gear": steering_gear,
    }


def list_examples() -> list[str]:
    """Names of the bundled model files (``<name>.toml`` in this folder), sorted."""
    return sorted(p.stem for p in _Path(__file__).parent.glob("*.toml"))


#: the benchmarks group: published benchmark problems (the IFToMM library's), larger than
#: the examples, in the folder ``benchmarks/`` (:mod:`.iftomm_examples`)
BENCHMARKS = _Path(__file__).parent / "benchmarks"


def list_benchmarks() -> list[str]:
    """Names of the bundled benchmark model files (``benchmarks/<name>.toml``), sorted."""
    return sorted(p.stem for p in BENCHMARKS.glob("*.toml"))


def example_path(name: str) -> _Path:
    """Path of the bundled model file ``<name>.toml``, an example or a benchmark;
    :class:`~appell.errors.ModelError` if none."""
    for folder in (_Path(__file__).parent, BENCHMARKS):
        path = folder / f"{name}.toml"
        if path.is_file():
            return path
    from appell.errors import ModelError

    raise ModelError(
        f"no bundled example {name!r}",
        hint="examples: " + ", ".join(list_examples()) + "; benchmarks: " + ", ".join(list_benchmarks()),
    )


__all__ = [
    "BENCHMARKS",
    "BUILDERS",
    "CATALOG",
    "car",
    "chaplygin_sleigh",
    "cone_particle",
    "cubic_acceleration",
    "example_path",
    "knife_edge",
    "list_benchmarks",
    "list_examples",
    "pendulum",
    "rolling_ball",
]
