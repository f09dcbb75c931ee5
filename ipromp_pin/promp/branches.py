"""Demos of one task that reach their hand-overs on different branches of the arm's inverse
kinematics (elbow up and elbow down, the wrist flipped, ...).

A task's Gaussian over joint-angle weights averages its demos: on one branch the mean configuration
puts the gripper near the demos' mean hand-over position (the forward kinematics is smooth over
the spread of the demos), across branches it puts it somewhere none of them went, often far from
every demo (a 6-joint arm's elbow half-way between up and down). :func:`mixed_branch_tasks` measures
it per task with the robot's forward kinematics: the distance from the demos' mean hand-over
position to the gripper position of their mean hand-over configuration, against the demos' own
spread around their mean position. Measured on demos of one branch (Baxter's recordings of both
shared datasets and its synthetic demos, the UR5's synthetic demos at its placement): at most 0.26
of the spread (1.9 cm for 7.4 cm); on the UR5's synthetic demos at a placement where they mix
branches: 3.3 to 6.3 times the spread (11.8 to 42.7 cm).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping

import numpy as np

MIN_OFFSET_M = 0.02
"""A mean configuration's gripper within this distance [m] of the demos' mean hand-over position is
never called mixed (demos of nearly one hand-over position have nearly no spread to compare with)."""


class MixedBranchesWarning(UserWarning):
    """A task's demos reach their hand-overs on different branches of the arm's inverse kinematics:
    the model averages them into configurations none of them took."""


def mixed_branch_tasks(
    q_end: Mapping[str, np.ndarray], fk: Callable[[np.ndarray], np.ndarray]
) -> list[tuple[str, float, float]]:
    """Of the tasks' final configurations ``q_end`` (task -> (N, J) [rad]; e.g.
    :func:`~ipromp_pin.promp.handover_selection.final_configurations`), those whose mean puts the
    gripper (``fk``: joint angles (n, J) [rad] -> positions (n, 3) [m]) farther from the demos' mean
    hand-over position than the median distance of the demos' own hand-overs from it (and than
    :data:`MIN_OFFSET_M`): (task, that distance [m], the median distance [m]) each, in the tasks'
    order."""
    out = []
    for task, q in q_end.items():
        q = np.asarray(q, dtype=float)
        if q.shape[0] < 2:
            continue
        pos = np.asarray(fk(q), dtype=float)
        centre = pos.mean(axis=0)
        offset = float(np.linalg.norm(np.asarray(fk(q.mean(axis=0)[None]), dtype=float)[0] - centre))
        spread = float(np.median(np.linalg.norm(pos - centre, axis=1)))
        if offset > max(spread, MIN_OFFSET_M):
            out.append((task, offset, spread))
    return out


def warn_mixed_branches(q_end: Mapping[str, np.ndarray], fk: Callable[[np.ndarray], np.ndarray]) -> None:
    """A :class:`MixedBranchesWarning` per task of :func:`mixed_branch_tasks`."""
    for task, offset, spread in mixed_branch_tasks(q_end, fk):
        where = f"{offset * 100:.1f} cm from their mean hand-over position"
        spread_cm = f"{spread * 100:.1f} cm"
        message = (
            f"task '{task}': the mean of its demos' hand-over configurations puts the gripper {where} "
            f"(the demos lie {spread_cm} from it, median): they reach it on different branches of "
            "the arm's inverse kinematics (elbow up and down, wrist flipped), which the model "
            "averages into configurations none of them took; record the task's demos on one branch"
        )
        warnings.warn(MixedBranchesWarning(message), stacklevel=4)  # at the caller of IProMP.fit
