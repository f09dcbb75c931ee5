"""``self_collision``: the arm certified free of contact with itself and the robot's fixed links along
the whole motion, between its samples as well as at them.

The certification is :class:`~ipromp_pin.robot.clearance.ClearanceCertifier`'s: per collision pair a
Lipschitz bound of the distance over joint-space balls around configurations where the distance was
computed (Pinocchio + coal), covering the piecewise-linear path through the samples. The balls are
kept and reused, so the successive motions of a closed loop (or the re-timings of one plan) cost few
new distance computations. The reported distance is the smallest computed distance among the
configurations whose balls certify the motion, near the sample where the certified room is
tightest.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import Trajectory
from ..robot import Robot
from ..robot.clearance import ClearanceCertifier
from .base import Check
from .context import CheckContext
from .verdict import Measures, Verdict


@dataclass(frozen=True)
class SelfCollisionMeasures(Measures):
    """Attributes:
    min_distance_m: Smallest computed distance [m] among the configurations certifying the motion
        (0 on failure).
    certified: Whether the whole motion is certified above the clearance.
    pair: Geometry names of the deciding pair.
    links: Their links.
    sample: Sample where the deciding pair is tightest, or where the certification failed.
    t_s: Its time [s].
    n_distances: Pair distances computed for this motion.
    min_clearance_m: The required clearance [m].
    """

    min_distance_m: float
    certified: bool
    pair: list[str]
    links: list[str]
    sample: int
    t_s: float
    n_distances: int
    min_clearance_m: float


class SelfCollision(Check):
    """Certified self-collision clearance (see the module docstring).

    Args:
        robot: The loaded robot (its collision model and the settings' ``min_clearance_m``).
        certifier: The certifier to use (default: one of this check's own, made on first use).
    """

    name = "self_collision"
    measures_type = SelfCollisionMeasures
    depends_on = "path"

    def __init__(self, robot: Robot, certifier: ClearanceCertifier | None = None) -> None:
        super().__init__(robot)
        self.certifier_ = certifier

    @property
    def certifier(self) -> ClearanceCertifier:
        """The certifier (made on first use, then kept with its balls)."""
        if self.certifier_ is None:
            self.certifier_ = ClearanceCertifier(self.robot)
        return self.certifier_

    def prime(self, paths: Iterable[np.ndarray]) -> None:
        """Certify ``paths`` (each (N, n_joints) [rad], e.g. the demonstrated motions) so that their
        distances are known before the first motion is checked."""
        for q in paths:
            self.certifier.certify(q)

    def reset(self) -> None:
        """Forget every computed distance (so that a run does not depend on the ones before it)."""
        if self.certifier_ is not None:
            self.certifier_.clear()

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        cert = self.certifier
        r = cert.certify(motion.q)
        sample = r.sample if not r.certified else cert.closest_sample(motion.q, r.pair_id)
        sample = min(max(int(sample), 0), motion.n_samples - 1)
        m = SelfCollisionMeasures(
            min_distance_m=r.min_distance_m,
            certified=r.certified,
            pair=list(r.pair),
            links=list(r.links),
            sample=sample,
            t_s=float(motion.t_s[sample]),
            n_distances=r.n_distances,
            min_clearance_m=r.clearance_m,
        )
        where = f"{r.links[0]} - {r.links[1]} near t={m.t_s:.2f} s"
        if r.collision:
            reason = f"self-collision: distance <= {r.clearance_m * 1e3:.1f} mm between {where}"
            return Verdict(self.name, "fail", reason, m)
        if not r.certified:
            return Verdict(self.name, "fail", f"clearance not certified between {where}", m)
        reason = (
            f"certified free of contact between samples; closest computed distance "
            f"{r.min_distance_m * 1e3:.1f} mm ({where})"
        )
        return Verdict(self.name, "pass", reason, m)
