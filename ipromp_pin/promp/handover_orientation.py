"""The hand-over orientation estimate: the gripper's rotation at the hand-over drawn toward the
recognised task's mean hand-over rotation, without moving the hand-over position.

The prediction of the final configuration ``q(T)`` (J,) in [rad] fixes the gripper position well (the
hand-over regression of :mod:`~ipromp_pin.promp.handover` acts on it); its orientation comes along
through the arm's null space and is often farther from the recorded one than the task's mean
hand-over rotation is. With the gripper's rotations known at fit time, the model holds per task

* ``P`` (3, J): the Jacobian of the gripper position at the task's mean final configuration
  ``q_bar`` ([m/rad]) and ``O`` (3, J): the rotational Jacobian there, in the base frame
  ([rad/rad]; :func:`rotation_readouts`);
* ``y`` (3,): the task's mean hand-over rotation in the same linearisation, ``O q_bar + mean_i
  log(R_i R(q_bar)^T)`` ([rad]), and ``N`` (3, 3): the second moment of the demos' leave-one-out
  deviations from it ([rad^2]);
* ``s``: a trust factor chosen by cross-validation of the orientation error on the training demos
  (:func:`~ipromp_pin.promp.orientation_selection.choose_orientation`; "off" is a candidate).

Online the prediction, with mean ``m`` and covariance ``S`` of ``q(T)``, is conditioned exactly
(:meth:`~ipromp_pin.promp.conditioning.Conditioner.observe_handover`) on an observation of the part of
the orientation that is uncorrelated with the position under ``S``: the read-out ``O' = O - B P``,
``B = O S P^T (P S P^T)^-1``, observed as ``y - B P m`` with noise ``s N``. Since ``P S O'^T = 0``,
the update leaves the linearised position's mean and covariance exactly as they were, and moves the
orientation by ``S O'^T (O' S O'^T + s N)^-1 (y - O m)``: the innovation of the orientation itself.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial.transform import Rotation

from .handover import JACOBIAN_STEP_RAD

ORIENTATION_TRUST_GRID = (0.03, 0.1, 0.3, 1.0, 3.0)
"""Candidate trust factors ``s`` (the observation's noise is ``s N``); "off" is also a candidate."""

FKRot = Callable[[np.ndarray], np.ndarray]
"""Gripper rotations: joint angles (n, J) in [rad] -> rotation matrices (n, 3, 3) in the base frame."""


def rotation_log(rot: np.ndarray) -> np.ndarray:
    """Rotation vectors (n, 3) in [rad] (axis times angle) of rotation matrices (n, 3, 3)."""
    return Rotation.from_matrix(np.asarray(rot, dtype=float).reshape(-1, 3, 3)).as_rotvec()


def rotation_readouts(q_bar: np.ndarray, fk_rot: FKRot) -> np.ndarray:
    """Per configuration of ``q_bar`` (T, J) in [rad], the gripper's rotational Jacobian (T, 3, J) in
    the base frame: column j is the angular velocity in [rad/s] of a unit speed of joint j (central
    differences of ``R(q + e) R(q)^T``)."""
    n_task, nj = q_bar.shape
    step = np.eye(nj) * JACOBIAN_STEP_RAD
    out = []
    for q in q_bar:
        rot = np.asarray(fk_rot(np.concatenate([q[None], q + step, q - step])), dtype=float)
        w = rotation_log(np.einsum("nij,kj->nik", rot[1:], rot[0]))
        out.append(((w[:nj] - w[nj:]) / (2.0 * JACOBIAN_STEP_RAD)).T)
    return np.stack(out).reshape(n_task, 3, nj)


def deviations(q_end: np.ndarray, q_bar: np.ndarray, fk_rot: FKRot) -> np.ndarray:
    """(N, 3) in [rad] the rotation vectors ``log(R_i R(q_bar)^T)`` of the final configurations
    ``q_end`` (N, J) relative to the rotation at ``q_bar`` (J,)."""
    rot = np.asarray(fk_rot(np.vstack([q_bar[None], q_end])), dtype=float)
    return rotation_log(np.einsum("nij,kj->nik", rot[1:], rot[0]))


def mean_and_noise(dev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean (3,) of deviations ``dev`` (N, 3), N >= 2, and the second moment (3, 3) of their
    leave-one-out residuals ``(dev_i - mean) N / (N - 1)`` (a small ridge keeps it positive definite)."""
    n = dev.shape[0]
    mean = dev.mean(axis=0)
    e = (dev - mean) * (n / (n - 1.0))
    cov = e.T @ e / n
    return mean, cov + 1e-9 * max(float(np.trace(cov)) / 3.0, 1e-12) * np.eye(3)


def spd_factor(m: np.ndarray) -> tuple[np.ndarray, bool]:
    """The lower Cholesky factor (``scipy.linalg.cho_factor``) of a symmetric positive semi-definite
    matrix (n, n), symmetrised and with a jitter of 1e-12 times its mean diagonal, so that a covariance
    made (numerically) singular by earlier conditioning still factorises."""
    sym = 0.5 * (m + m.T)
    jitter = 1e-12 * max(float(np.trace(sym)) / sym.shape[0], 1e-300)
    return cho_factor(sym + jitter * np.eye(sym.shape[0]), lower=True)


def position_preserving(
    rotation_readout: np.ndarray,
    position_readout: np.ndarray,
    target: np.ndarray,
    mean: np.ndarray,
    cov: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The read-out ``O' = O - B P`` (3, J) and its value ``y - B P m`` (3,) (module docstring) for
    the final configuration's mean ``m`` (J,) [rad] and covariance ``S`` (J, J) [rad^2]."""
    sp = cov @ position_readout.T  # (J, 3)
    c = spd_factor(position_readout @ sp)
    b = cho_solve(c, sp.T @ rotation_readout.T).T  # O S P^T (P S P^T)^-1, (3, 3)
    return rotation_readout - b @ position_readout, target - b @ (position_readout @ mean)


def conditioned(
    readout: np.ndarray, value: np.ndarray, noise: np.ndarray, mean: np.ndarray, cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mean (J,) and covariance (J, J) of ``q(T) ~ N(mean, cov)`` conditioned on ``value = readout
    q(T) + e``, ``e ~ N(0, noise)`` (Cholesky solves)."""
    g = cov @ readout.T
    c = spd_factor(readout @ g + noise)
    out_mean = mean + g @ cho_solve(c, value - readout @ mean)
    out_cov = cov - g @ cho_solve(c, g.T)
    return out_mean, 0.5 * (out_cov + out_cov.T)


@dataclass(frozen=True)
class OrientationEstimate:
    """The fitted hand-over orientation estimate of every task (see the module docstring).

    Attributes:
        position_readout: (T, 3, J) per task the gripper position's Jacobian ``P`` in [m/rad].
        rotation_readout: (T, 3, J) per task the rotational Jacobian ``O`` in [rad/rad].
        target: (T, 3) per task the mean hand-over rotation ``y`` in the linearisation, in [rad].
        noise_cov: (T, 3, 3) per task ``N`` in [rad^2].
        trust: The trust factor ``s`` (the noise covariance is ``s N``).
    """

    position_readout: np.ndarray
    rotation_readout: np.ndarray
    target: np.ndarray
    noise_cov: np.ndarray
    trust: float

    def __post_init__(self) -> None:
        for name in ("position_readout", "rotation_readout", "target", "noise_cov"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=float))

    def observation(
        self, task: int, mean: np.ndarray, cov: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The read-out (3, J), its value (3,) and noise covariance (3, 3) of task index ``task`` for a
        prediction whose final configuration has mean ``mean`` (J,) [rad] and covariance ``cov``
        (J, J) [rad^2]."""
        readout, value = position_preserving(
            self.rotation_readout[task], self.position_readout[task], self.target[task], mean, cov
        )
        return readout, value, self.trust * self.noise_cov[task]
