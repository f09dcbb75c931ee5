"""Fitting the hand-over orientation estimate and choosing its trust factor, on the training demos only.

The estimate (:mod:`~ipromp_pin.promp.handover_orientation`) needs the gripper's rotations at fit
time. Its trust factor ``s`` is chosen by cross-validation on the held-out rows of the hand-over
regression's cross-validation (:mod:`~ipromp_pin.promp.handover_selection`): each row is the robot
predicted as online for a held-out demo at one observed fraction (leave-one-out model, the chosen
hand-over regression applied), conditioned again as online on the orientation estimate of its task
without the held-out demo (its mean rotation and noise from the other demos); the score of every
candidate of :data:`~ipromp_pin.promp.handover_orientation.ORIENTATION_TRUST_GRID` and of "off" is
the mean geodesic angle in [deg] between the predicted and the recorded hand-over rotations; the
best one is chosen ("off": the model has no orientation estimate).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .handover import readouts
from .handover_orientation import (
    ORIENTATION_TRUST_GRID,
    FKRot,
    OrientationEstimate,
    conditioned,
    deviations,
    mean_and_noise,
    position_preserving,
    rotation_log,
    rotation_readouts,
)


@dataclass(frozen=True)
class FinalRow:
    """One held-out prediction of a final configuration: its demo (task, index within the task), the
    mean (J,) in [rad] and covariance (J, J) in [rad^2] of its final joint angles."""

    task: str
    index: int
    mean: np.ndarray
    cov: np.ndarray


@dataclass(frozen=True)
class OrientationChoice:
    """What :func:`choose_orientation` chose.

    Attributes:
        estimate: The orientation estimate (None: "off", or too few demos).
        scores: Candidate trust factor -> CV error (mean hand-over orientation error in [deg]);
            ``inf`` is "off".
    """

    estimate: OrientationEstimate | None
    scores: dict[float, float]


def angles_deg(rot_a: np.ndarray, rot_b: np.ndarray) -> np.ndarray:
    """Geodesic angles (n,) in [deg] between rotation matrices ``rot_a`` and ``rot_b`` (n, 3, 3)."""
    rel = np.einsum("nji,njk->nik", rot_a, rot_b)
    return np.degrees(np.linalg.norm(rotation_log(rel), axis=1))


def choose_orientation(
    rows: Sequence[FinalRow],
    q_end: dict[str, np.ndarray],
    tasks: Sequence[str],
    fk: Callable[[np.ndarray], np.ndarray],
    fk_rot: FKRot,
) -> OrientationChoice:
    """Fit the orientation estimate of every task and choose its trust factor (module docstring).

    Args:
        rows: The held-out predictions of the final configurations, as online.
        q_end: Task -> (N, J) the recorded final joint angles in [rad] of its training demos.
        tasks: Task names, in the model's order.
        fk: Forward kinematics, joint angles (n, J) in [rad] -> gripper positions (n, 3) in [m].
        fk_rot: Gripper rotations, joint angles (n, J) in [rad] -> rotation matrices (n, 3, 3).
    """
    if any(q_end[t].shape[0] < 3 for t in tasks):  # a leave-one-out spread needs two others
        return OrientationChoice(None, {})
    q_bar = np.stack([q_end[t].mean(axis=0) for t in tasks])
    position = readouts(q_bar, fk)
    rotation = rotation_readouts(q_bar, fk_rot)
    dev = {t: deviations(q_end[t], q_bar[k], fk_rot) for k, t in enumerate(tasks)}
    configs, truths = [], []
    for row in rows:
        k = tasks.index(row.task)
        keep = np.arange(q_end[row.task].shape[0]) != row.index
        mean_dev, noise = mean_and_noise(dev[row.task][keep])
        target = rotation[k] @ q_bar[k] + mean_dev
        readout, value = position_preserving(rotation[k], position[k], target, row.mean, row.cov)
        outs = [row.mean]
        for trust in ORIENTATION_TRUST_GRID:
            outs.append(conditioned(readout, value, trust * noise, row.mean, row.cov)[0])
        configs.append(np.stack(outs))
        truths.append(q_end[row.task][row.index])
    if not configs:
        return OrientationChoice(None, {})
    q = np.stack(configs)  # (n, 1 + len(ORIENTATION_TRUST_GRID), J)
    n, c, nj = q.shape
    rot = np.asarray(fk_rot(np.concatenate([np.stack(truths), q.reshape(-1, nj)])), dtype=float)
    truth_rot = np.repeat(rot[:n], c, axis=0)
    err = angles_deg(rot[n:], truth_rot).reshape(n, c).mean(axis=0)
    scores = {np.inf: float(err[0])}
    scores.update({t: float(v) for t, v in zip(ORIENTATION_TRUST_GRID, err[1:], strict=True)})
    trust = min(scores, key=lambda v: scores[v])
    if not np.isfinite(trust):
        return OrientationChoice(None, scores)
    stats = [mean_and_noise(dev[t]) for t in tasks]
    estimate = OrientationEstimate(
        position_readout=position,
        rotation_readout=rotation,
        target=np.stack([rotation[k] @ q_bar[k] + stats[k][0] for k in range(len(tasks))]),
        noise_cov=np.stack([s[1] for s in stats]),
        trust=float(trust),
    )
    return OrientationChoice(estimate, scores)
