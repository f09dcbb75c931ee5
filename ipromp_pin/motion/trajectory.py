"""The objects that planning, checks and outputs exchange: joint limits and a timed joint motion.

:class:`JointLimits` holds an arm's position, velocity, acceleration and jerk limits (arrays in [rad],
[rad/s], [rad/s^2], [rad/s^3]) and validates them once; :class:`Trajectory` is a joint motion sampled
at a fixed control period on the human's clock, the only timed-motion type of the package:
:mod:`~ipromp_pin.motion.timing` (toppra + ruckig) and :mod:`~ipromp_pin.motion.retarget` produce
it, :mod:`ipromp_pin.safety` checks it, :mod:`ipromp_pin.planning` commands it and
:mod:`ipromp_pin.outputs` writes it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..exceptions import InfeasibleError

__all__ = ["JointLimits", "MotionState", "Trajectory"]


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


@dataclass(frozen=True)
class MotionState:
    """The commanded state of the arm at one control tick.

    Attributes:
        t_s: Time in [s] on the human's clock.
        q: Positions (n_joints,) in [rad].
        qd: Velocities (n_joints,) in [rad/s].
        qdd: Accelerations (n_joints,) in [rad/s^2].
    """

    t_s: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    @classmethod
    def at_rest(cls, t_s: float, q: np.ndarray) -> MotionState:
        """The state at rest at ``q`` (n_joints,) in [rad]."""
        q = np.asarray(q, dtype=float).reshape(-1)
        return cls(float(t_s), q, np.zeros_like(q), np.zeros_like(q))


@dataclass
class Trajectory:
    """A joint motion sampled at a fixed control period: the one timed-motion type that timing,
    re-targeting, checks, scores and outputs exchange.

    Times are on the clock of the human's motion (t = 0 where the human starts moving, the time
    base of the recordings and of the closed loop), so a motion planned after an observation starts
    at the end of that observation; :meth:`shifted` moves it to another origin.

    Attributes:
        t_s: Sample times (N,) in [s], uniformly spaced (one control period apart).
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

    @classmethod
    def at_rest(
        cls, t_s: float, q: np.ndarray, joint_names: tuple[str, ...], n: int = 1, dt_s: float = 0.0
    ) -> Trajectory:
        """``n`` samples ``dt_s`` [s] apart from ``t_s`` [s] at rest at ``q`` (n_joints,) [rad]."""
        q = np.asarray(q, dtype=float).reshape(1, -1)
        z = np.zeros((n, q.shape[1]))
        t = float(t_s) + np.arange(n) * float(dt_s)
        return cls(t, np.repeat(q, n, axis=0), z, z.copy(), tuple(joint_names), z.copy())

    @property
    def duration_s(self) -> float:
        """Duration in [s] (last minus first sample time)."""
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def start_s(self) -> float:
        """Time of the first sample in [s]."""
        return float(self.t_s[0])

    @property
    def end_s(self) -> float:
        """Time of the last sample in [s]."""
        return float(self.t_s[-1])

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t_s.size)

    @property
    def dt_s(self) -> float:
        """Control period in [s] (0 for a single sample)."""
        return float(self.t_s[1] - self.t_s[0]) if self.t_s.size > 1 else 0.0

    def state(self, i: int) -> MotionState:
        """The state at sample ``i`` (at rest at the last position after the last sample), at
        ``t_s[0] + i dt`` [s]."""
        t = self.start_s + i * self.dt_s
        if i >= self.n_samples:
            return MotionState.at_rest(t, self.q[-1])
        j = max(int(i), 0)
        return MotionState(t, self.q[j].copy(), self.qd[j].copy(), self.qdd[j].copy())

    def jerk(self) -> np.ndarray:
        """Jerk (N, n_joints) in [rad/s^3]: the exact values when known, else finite differences of qdd."""
        if self.qddd is not None:
            return self.qddd
        j = np.zeros_like(self.qdd)
        if self.t_s.size > 1:
            j[1:] = np.diff(self.qdd, axis=0) / np.diff(self.t_s)[:, None]
        return j

    def shifted(self, dt_s: float) -> Trajectory:
        """The same samples with every time moved by ``dt_s`` [s] (arrays shared, not copied)."""
        return dataclasses.replace(self, t_s=self.t_s + float(dt_s))

    def then(self, other: Trajectory) -> Trajectory:
        """This motion followed by ``other``'s samples after its first (which must be this motion's last
        state, e.g. a retreat from the hand-over), ``other``'s times continued from this one's end.
        The jerks and efforts are kept where both motions have them."""
        if other.n_samples < 2:
            return self
        shift = self.end_s - other.start_s

        def join(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
            return None if a is None or b is None else np.vstack([a, b[1:]])

        return Trajectory(
            np.concatenate([self.t_s, other.t_s[1:] + shift]),
            np.vstack([self.q, other.q[1:]]),
            np.vstack([self.qd, other.qd[1:]]),
            np.vstack([self.qdd, other.qdd[1:]]),
            self.joint_names,
            join(self.jerk(), other.jerk()),
            join(self.effort_nm, other.effort_nm),
        )
