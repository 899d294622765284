"""The multibody front end: bodies, frames and joints in; an :class:`appell.System` with
joint reactions (forces and moments) as outputs (docs/mechanism.md).

Model level: imports only :mod:`appell.model`, :mod:`appell.errors`, :mod:`appell.symbols`.
"""

from appell.mechanism.builder import GROUND, Body, Frame, Joint, Mechanism
from appell.mechanism.joints import KINDS, JointMotion, joint_motion
from appell.mechanism import rotations

__all__ = ["GROUND", "Body", "Frame", "Joint", "JointMotion", "KINDS", "Mechanism", "joint_motion", "rotations"]
