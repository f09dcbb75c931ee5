"""The objects that planning, checks and outputs exchange: joint limits and a timed joint trajectory.

:class:`JointLimits` holds an arm's position, velocity, acceleration and jerk limits (arrays in [rad],
[rad/s], [rad/s^2], [rad/s^3]) and validates them once; :class:`Trajectory` is a trajectory sampled at
a fixed control rate. :mod:`ipromp_pin.motion.timing` produces trajectories,
:mod:`ipromp_pin.outputs.trajectory_files` and :mod:`ipromp_pin.outputs.rosbag` write them,
:mod:`ipromp_pin.handover.closed_loop` commands them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InfeasibleError

__all__ = ["JointLimits", "Trajectory"]


@dataclass(frozen=True)
class JointLimits:
    """Joint limits of an arm, all arrays (n_joints,).

    Attributes:
        lower_rad: Position lower limits in [rad] (margins already applied).
        upper_rad: Position upper limits in [rad].
        velocity_rad_s: Velocity limits in [rad/s].
        acceleration_rad_s2: Acceleration limits in [rad/s^2].
        jerk_rad_s3: Jerk limits in [rad/s^3].
        joint_names: Joint names in order.
    """

    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray
    jerk_rad_s3: np.ndarray
    joint_names: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        for name in ("lower_rad", "upper_rad", "velocity_rad_s", "acceleration_rad_s2", "jerk_rad_s3"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,):
                raise InfeasibleError(f"JointLimits.{name}: expected shape ({n},), got {v.shape}")
            if not np.all(np.isfinite(v)):
                raise InfeasibleError(f"JointLimits.{name}: values must be finite, got {v.tolist()}")
            if name not in ("lower_rad", "upper_rad") and np.any(v <= 0):
                raise InfeasibleError(f"JointLimits.{name}: values must be positive, got {v.tolist()}")
            object.__setattr__(self, name, v)
        if np.any(self.lower_rad >= self.upper_rad):
            j = int(np.argmax(self.lower_rad >= self.upper_rad))
            raise InfeasibleError(
                f"JointLimits: lower limit {self.lower_rad[j]} >= upper limit {self.upper_rad[j]} "
                f"for {self.joint_names[j]}"
            )

    @classmethod
    def from_robot(cls, robot, margin: bool = True) -> JointLimits:
        """Limits of a loaded :class:`~ipromp_pin.robot.Robot` (URDF positions/velocities, settings
        accelerations/jerks; positions shrunk by the settings' margin when ``margin``)."""
        s = robot.settings
        m = s.position_margin_rad if margin else np.zeros(robot.n_joints)
        return cls(
            lower_rad=robot.lower_rad + m,
            upper_rad=robot.upper_rad - m,
            velocity_rad_s=robot.velocity_rad_s,
            acceleration_rad_s2=s.acceleration_rad_s2,
            jerk_rad_s3=s.jerk_rad_s3,
            joint_names=robot.joint_names,
        )

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    def scaled(self, velocity: float = 1.0, acceleration: float = 1.0, jerk: float = 1.0) -> JointLimits:
        """Copy with velocity/acceleration/jerk limits multiplied by the given factors."""
        return JointLimits(
            self.lower_rad,
            self.upper_rad,
            self.velocity_rad_s * velocity,
            self.acceleration_rad_s2 * acceleration,
            self.jerk_rad_s3 * jerk,
            self.joint_names,
        )


@dataclass
class Trajectory:
    """A time-parameterised joint trajectory sampled at a fixed control rate.

    Attributes:
        t_s: Sample times (N,) in [s], from 0.
        q: Positions (N, n_joints) in [rad].
        qd: Velocities (N, n_joints) in [rad/s].
        qdd: Accelerations (N, n_joints) in [rad/s^2].
        joint_names: Joint names in column order.
        qddd: Jerks (N, n_joints) in [rad/s^3] when known (``None`` after reading from a file).
        effort_nm: Joint torques (N, n_joints) in [N m] the motion needs, when computed (the joint-torque
            check's inverse dynamics, payload included; written as the messages' ``effort``).
    """

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    joint_names: tuple[str, ...]
    qddd: np.ndarray | None = None
    effort_nm: np.ndarray | None = None

    @property
    def duration_s(self) -> float:
        """Duration in [s]."""
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t_s.size)

    def jerk(self) -> np.ndarray:
        """Jerk (N, n_joints) in [rad/s^3]: the exact values when known, else finite differences of qdd."""
        if self.qddd is not None:
            return self.qddd
        j = np.zeros_like(self.qdd)
        if self.t_s.size > 1:
            j[1:] = np.diff(self.qdd, axis=0) / np.diff(self.t_s)[:, None]
        return j
