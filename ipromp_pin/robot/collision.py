"""Contact tests of the arm with itself and the robot's fixed links (Pinocchio + coal).

:func:`in_collision` answers, per configuration, whether an active collision pair (the SRDF's
disabled pairs removed) is in contact: the scores' test of every commanded sample and the advisory
uncertainty check's. Distances and their certification along a motion are
:mod:`~ipromp_pin.robot.clearance`'s (the ``self_collision`` check of :mod:`ipromp_pin.safety`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .model import Robot


def in_collision(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Whether each configuration (n, n_joints) in [rad] has a contact among the active pairs (n,).

    A contact test only, no distances: coal's narrow phase for the active pairs whose bounding boxes
    overlap, found by a sweep-and-prune broad phase (Pinocchio's ``BroadPhaseManager``, built per
    call: 0.06 ms). The same answers as testing every active pair (tests), 4-13x faster on the
    shipped Baxter (371 active pairs; 61 / 24 us against 250 / 315 us per configuration on random
    configurations / a smooth path).
    """
    model, data = robot.model, robot.data
    cmodel, cdata = robot.collision()
    manager = pin.BroadPhaseManager_SSaPCollisionManager(model, cmodel, cdata)
    full = robot.full_configuration(q)
    hits = [pin.computeCollisions(model, data, manager, row, True) for row in full]
    return np.array(hits, dtype=bool)
