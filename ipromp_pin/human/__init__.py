"""The human side of the feasibility checks: the body model and the ISO/TS 15066:2016 limits (their
content now in ISO 10218-2:2025; clause numbers below are the ISO/TS's, ``docs/safety.md``).

* :mod:`~ipromp_pin.human.body`: :class:`HumanMotion`, body parts as capsules between tracked
  skeleton frames (or an assumed standing human), over time, with occlusions inflated;
* :mod:`~ipromp_pin.human.iso15066`: the protective separation distance (clause 5.5.4) and the
  power-and-force-limiting contact speed (clause 5.5.5, Annex A) with the robot's effective mass.
"""

from .body import ASSUMED_POSE_M, BODY_PARTS, SKELETON_PREFIX, BodyPart, HumanMotion

__all__ = ["ASSUMED_POSE_M", "BODY_PARTS", "SKELETON_PREFIX", "BodyPart", "HumanMotion"]
