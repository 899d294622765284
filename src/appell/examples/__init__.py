"""Bundled examples: Python builders (:mod:`.catalog`) and model files in this folder."""

from .catalog import CATALOG, car, chaplygin_sleigh, cone_particle, cubic_acceleration, knife_edge, pendulum, rolling_ball

__all__ = ["CATALOG", "car", "chaplygin_sleigh", "cone_particle", "cubic_acceleration", "knife_edge", "pendulum",
           "rolling_ball"]
