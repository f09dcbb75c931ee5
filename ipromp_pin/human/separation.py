"""Separation between the robot and the human body along a timed joint motion, with ISO/TS 15066.

:class:`SeparationAnalyser` (one per robot: the capsules of its collision geometry are fitted once)
computes, at every sample of a motion (times ``t_s`` on the human's clock, angles ``q``, velocities
``qd``), the distance between every robot capsule ``l`` and every body capsule ``p``
(:mod:`.robot_capsules`, :mod:`.body`), the approach speed of the robot's closest point toward the
body part (its velocity, from the point Jacobian, projected on the separation direction), the
protective separation distance ``S_p`` at that speed, and, where the pair is closer than ``S_p``, the
ratio of the approach speed to the body region's contact-speed limit ``v_max`` (:mod:`.iso15066`;
the effective mass is computed only where the speed exceeds the limit of an infinitely heavy robot,
which no effective mass can lower). :class:`Separation` holds the per-sample results that the checks
``human_clearance`` and ``contact_speed`` judge and that previews draw.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np

from ..exceptions import DataError
from ..robot import Robot
from ..robot.human_settings import HumanSettings
from .body import HumanMotion
from .iso15066 import (
    ArmInertia,
    constant_distance_m,
    reduced_mass_kg,
    region_force_n,
    speed_bound_any_robot_m_s,
)
from .kernels import human_kernels
from .robot_capsules import (
    RobotCapsules,
    arm_kinematics,
    fit_robot_capsules,
)

HAND_REGION = "hand"
"""The body region of the intended hand-over contact: judged by its contact-speed limit only."""


def _sample_period_s(t_s: np.ndarray) -> float:
    """The median period [s] of the sample times ``t_s`` (N,) [s] (0 for a single sample)."""
    return float(np.median(np.diff(t_s))) if t_s.size > 1 else 0.0


class _SampledRatios(Protocol):
    """What :class:`SeparationReductions` reads: sample times, S_p states and contact-speed ratios."""

    @property
    def t_s(self) -> np.ndarray: ...

    @property
    def within_sp(self) -> np.ndarray: ...

    @property
    def max_ratio(self) -> np.ndarray: ...


class SeparationReductions:
    """The per-sample reductions that :class:`Separation` and its summary
    (:class:`~.separation_summary.SeparationSummary`) share, from their sample times ``t_s`` (N,)
    [s], ``within_sp`` (N,) and ``max_ratio`` (N,)."""

    @property
    def dt_s(self: _SampledRatios) -> float:
        """Sample period in [s] (0 for a single sample)."""
        return _sample_period_s(self.t_s)

    @property
    def violation(self: _SampledRatios) -> np.ndarray:
        """(N,) whether, within S_p, the robot approaches some body part faster than its limit."""
        return self.max_ratio > 1.0

    def over(self: _SampledRatios, fraction: float) -> np.ndarray:
        """(N,) whether, within S_p, some approach exceeds ``fraction`` of its limit."""
        return self.max_ratio > fraction

    @property
    def time_within_sp_s(self: _SampledRatios) -> float:
        """Time in [s] during which the robot is closer than S_p to some body part."""
        return float(np.count_nonzero(self.within_sp) * _sample_period_s(self.t_s))


@dataclass(frozen=True)
class Separation(SeparationReductions):
    """Robot-body separation along a motion (N samples; L robot capsules, P body parts).

    Attributes:
        t_s: Sample times (N,) [s] on the human's clock.
        distance_m: Distances (N, L, P) [m] to the body capsules with their uncertainty inflation
            (occluded or not yet observed frames; negative: overlap): where contact cannot be
            excluded, what S_p and the contact-speed limits are judged on.
        inflation_m: The inflation (N, P) [m] of each part: the distance to the part at its nominal
            (held or interpolated) position is ``distance_m + inflation_m``.
        approach_m_s: Approach speed (N, L, P) [m/s] of the robot's closest point toward the part.
        protective_m: S_p (N, L, P) [m] at that approach speed.
        speed_ratio: approach speed / v_max (N, L, P) where the pair is within S_p (0 elsewhere).
        robot_mass_kg: The robot's effective mass (N, L, P) [kg] where computed (NaN elsewhere).
        closest_robot_m: The robot's closest surface point (N, 3) [m] to the body (hand included).
        closest_body_m: The body's closest surface point (N, 3) [m].
        clearance_robot_m: The robot's surface point (N, 3) [m] of the pair closest to the body
            outside the hand at its nominal position (the pair of :meth:`clearance_pairs`; the
            closest pair's without a part outside the hand).
        clearance_body_m: That part's nominal surface point (N, 3) [m].
        links: Robot capsule links (L,).
        geometries: Robot capsule geometry names (L,).
        parts: Body part names (P,).
        regions: Body regions (P,).
        human: ``"tracked"``, ``"predicted"`` or ``"assumed"`` (:attr:`.body.HumanMotion.label`).
    """

    t_s: np.ndarray
    distance_m: np.ndarray
    inflation_m: np.ndarray
    approach_m_s: np.ndarray
    protective_m: np.ndarray
    speed_ratio: np.ndarray
    robot_mass_kg: np.ndarray
    closest_robot_m: np.ndarray
    closest_body_m: np.ndarray
    clearance_robot_m: np.ndarray
    clearance_body_m: np.ndarray
    links: tuple[str, ...]
    geometries: tuple[str, ...]
    parts: tuple[str, ...]
    regions: tuple[str, ...]
    human: str

    @cached_property
    def within_sp(self) -> np.ndarray:
        """(N,) whether any robot capsule is closer than S_p to any body part."""
        return np.any(self.distance_m < self.protective_m, axis=(1, 2))

    @cached_property
    def max_ratio(self) -> np.ndarray:
        """(N,) the largest approach speed / v_max within S_p (0: none within S_p and fast)."""
        return self.speed_ratio.max(axis=(1, 2))

    @property
    def min_distance_m(self) -> np.ndarray:
        """(N,) the smallest robot-body distance [m] (every part)."""
        return self.distance_m.min(axis=(1, 2))

    def nominal_distance_m(self) -> np.ndarray:
        """(N, L, P) distances [m] to the parts at their nominal positions (without inflation)."""
        return self.distance_m + self.inflation_m[:, None, :]

    def clearance_pairs(
        self, exclude_region: str | None = HAND_REGION
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per sample (N,): the smallest distance [m] to the nominal parts outside
        ``exclude_region`` (:meth:`clearance_m`) and the (capsule, part) indices of it, the pair
        :meth:`where` names with ``nominal=True``."""
        return clearance_pairs(self.distance_m, self.inflation_m, self.regions, exclude_region)

    def clearance_m(self, exclude_region: str | None = HAND_REGION) -> np.ndarray:
        """(N,) the smallest distance [m] to the nominal parts outside ``exclude_region``."""
        keep = np.array([r != exclude_region for r in self.regions])
        if not keep.any():
            return np.full(self.t_s.size, np.inf)
        d = self.distance_m[:, :, keep].min(axis=1) + self.inflation_m[:, keep]  # (N, P_kept)
        return d.min(axis=1)

    def state(self) -> np.ndarray:
        """(N,) per sample: 0 free, 1 within S_p, 2 within S_p and speed-limited (ratio > 0.8),
        3 violation (faster than the limit within S_p)."""
        ratio = self.max_ratio
        out = np.where(self.within_sp, 1, 0)
        out = np.where(self.within_sp & (ratio > 0.8), 2, out)
        return np.where(ratio > 1.0, 3, out)

    def where(
        self, n: int, exclude_region: str | None = None, nominal: bool = False
    ) -> tuple[str, str, float, float]:
        """(link, body part, t [s], distance [m]) of the closest pair at sample ``n`` (``nominal``:
        to the parts without their inflation)."""
        d = self.distance_m[n] + (self.inflation_m[n][None, :] if nominal else 0.0)
        if exclude_region is not None:
            d[:, [r == exclude_region for r in self.regions]] = np.inf
        li, pi = np.unravel_index(int(np.argmin(d)), d.shape)
        return self.links[li], self.parts[pi], float(self.t_s[n]), float(d[li, pi])


def clearance_pairs(
    distance_m: np.ndarray, inflation_m: np.ndarray, regions: tuple[str, ...], exclude_region: str | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample (N,) of distances ``distance_m`` (N, L, P) [m] with the parts' inflation
    ``inflation_m`` (N, P) [m]: the smallest distance [m] to the nominal parts whose region is not
    ``exclude_region`` and its capsule and part indices (the first in (capsule, part) order; inf and
    (0, 0) without such a part)."""
    n, nl, npart = distance_m.shape
    d = distance_m + inflation_m[:, None, :]
    d[:, :, [r == exclude_region for r in regions]] = np.inf
    flat = d.reshape(n, -1).argmin(axis=1)
    li, pi = np.unravel_index(flat, (nl, npart))
    return d.reshape(n, -1)[np.arange(n), flat], li, pi


def sample_groups(n_i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct samples of pair samples ``n_i`` (K,) and each pair's index among them (K,):
    ``np.unique(n_i, return_inverse=True)``, without its sort when ``n_i`` is already sorted (the
    pairs of the kernels and of ``np.nonzero`` are in sample order)."""
    n_i = np.asarray(n_i)
    if n_i.size and np.all(n_i[1:] >= n_i[:-1]):
        first = np.empty(n_i.size, dtype=bool)
        first[0] = True
        np.not_equal(n_i[1:], n_i[:-1], out=first[1:])
        return n_i[first], np.cumsum(first) - 1
    return np.unique(n_i, return_inverse=True)


class SeparationAnalyser:
    """Separation of a robot's motions from a human (see the module docstring).

    Args:
        robot: The loaded robot (its collision model is fitted by capsules on first use).
        settings: The human / ISO/TS 15066 settings (default: the robot's own).
    """

    def __init__(self, robot: Robot, settings: HumanSettings | None = None) -> None:
        self.robot = robot
        self.settings = settings if settings is not None else robot.settings.human
        self._capsules: RobotCapsules | None = None
        self._arm_inertia: ArmInertia | None = None
        self._last: tuple[tuple, Separation] | None = None
        self._limits: tuple[tuple, tuple[np.ndarray, ...]] | None = None

    @property
    def capsules(self) -> RobotCapsules:
        """The robot's capsules (fitted once)."""
        if self._capsules is None:
            self._capsules = fit_robot_capsules(self.robot)
        return self._capsules

    def analyse(self, t_s: np.ndarray, q: np.ndarray, qd: np.ndarray, human: HumanMotion) -> Separation:
        """The separation along a motion: times (N,) [s], angles and velocities (N, n_joints) [rad],
        [rad/s], against ``human``. The last result is kept: the same arrays and human again (two
        checks of one motion) return it without recomputing."""
        key = (t_s, q, qd, human)
        if self._last is not None and all(a is b for a, b in zip(self._last[0], key, strict=True)):
            return self._last[1]
        result = self._compute(np.asarray(t_s, dtype=float), q, qd, human)
        self._last = (key, result)  # the inputs are kept: their ids cannot be reused meanwhile
        return result

    def _compute(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, human: HumanMotion) -> Separation:
        kernels = human_kernels()
        caps, s = self.capsules, self.settings
        q = np.ascontiguousarray(q, dtype=float)
        qd = np.ascontiguousarray(qd, dtype=float)
        origins, axes, ra, rb = arm_kinematics(caps, q)
        times, at = np.unique(t, return_inverse=True)  # several configurations at one time: once
        ha, hb, hr = (x[at] for x in human.capsules(times)) if times.size < t.size else human.capsules(t)
        caps_radius_p = human.radius_m[None, :]
        if not (np.all(np.isfinite(ha)) and np.all(np.isfinite(hb)) and np.all(np.isfinite(hr))):
            raise DataError(human.source or "human", "body capsules", "non-finite position or radius")
        dist, cr, ch = kernels.capsule_distances(ra, rb, caps.radius_m, ha, hb, np.ascontiguousarray(hr))
        n, nl, npart = dist.shape
        t_r, t_stop = s.reaction_time_s, s.stopping_time_s
        sp_const = s.speed_m_s * (t_r + t_stop) + constant_distance_m(s)
        approach, protective, unit = kernels.approach_speeds(
            dist, cr, ch, caps.radius_m, origins, axes, qd, caps.anchor, sp_const, t_r + t_stop / 2.0
        )
        ratio = np.zeros(dist.shape)
        mass = np.full(dist.shape, np.nan)
        self._contact_ratios(dist, approach, protective, unit, cr, origins, axes, q, qd, human, ratio, mass)
        flat = dist.reshape(n, -1).argmin(axis=1)
        li, pi = np.unravel_index(flat, (nl, npart))
        rows = np.arange(n)
        u = np.nan_to_num(unit[rows, li, pi])
        inflation = hr - caps_radius_p
        if any(r != HAND_REGION for r in human.regions):
            _, lc, pc = clearance_pairs(dist, inflation, tuple(human.regions.tolist()), HAND_REGION)
        else:
            lc, pc = li, pi
        uc = np.nan_to_num(unit[rows, lc, pc])
        return Separation(
            t_s=t,
            distance_m=dist,
            inflation_m=inflation,
            approach_m_s=approach,
            protective_m=protective,
            speed_ratio=ratio,
            robot_mass_kg=mass,
            closest_robot_m=cr[rows, li, pi] + u * caps.radius_m[li][:, None],
            closest_body_m=ch[rows, li, pi] - u * hr[rows, pi][:, None],
            clearance_robot_m=cr[rows, lc, pc] + uc * caps.radius_m[lc][:, None],
            clearance_body_m=ch[rows, lc, pc] - uc * human.radius_m[pc][:, None],
            links=caps.links,
            geometries=caps.names,
            parts=tuple(human.part_names.tolist()),
            regions=tuple(human.regions.tolist()),
            human=human.label,
        )

    def contact_floor(self, human: HumanMotion) -> np.ndarray:
        """Per body part (P,) the approach speed [m/s] at or below which no pair reaches the planning
        limit ``(1 - speed_margin) v_max``: that fraction of the limit of an infinitely heavy robot."""
        return self._region_limits(human)[0]

    def _region_limits(self, human: HumanMotion) -> tuple[np.ndarray, ...]:
        """Per body part (P,) of ``human``: :meth:`contact_floor`, and its region's permissible force
        [N], effective mass [kg] and spring constant [N/m] (kept for the same parts)."""
        if self._limits is not None and self._limits[0] == human.parts:
            return self._limits[1]
        s = self.settings
        limits = [s.regions[str(r)] for r in human.regions]
        lower = np.array([speed_bound_any_robot_m_s(lim, s.contact) for lim in limits])
        values = (
            (1.0 - s.speed_margin) * lower,
            np.array([region_force_n(lim, s.contact) for lim in limits]),
            np.array([lim.mass_kg for lim in limits]),
            np.array([lim.spring_n_m for lim in limits]),
        )
        self._limits = (human.parts, values)
        return values

    def _contact_ratios(
        self,
        dist: np.ndarray,
        approach: np.ndarray,
        protective: np.ndarray,
        unit: np.ndarray,
        cr: np.ndarray,
        origins: np.ndarray,
        axes: np.ndarray,
        q: np.ndarray,
        qd: np.ndarray,
        human: HumanMotion,
        ratio: np.ndarray,
        mass: np.ndarray,
    ) -> None:
        """Effective mass and approach speed / v_max of the pairs within S_p that are faster than
        ``1 - speed_margin`` of the limit of an infinitely heavy robot (in place; no other pair can
        reach the planning limit ``(1 - speed_margin) v_max``)."""
        kernels = human_kernels()
        caps = self.capsules
        floor = self.contact_floor(human)  # below it, no pair reaches the planning limit
        need = (dist < protective) & (approach > floor[None, None, :])
        if not np.any(need):
            return
        n_i, l_i, p_i = (np.ascontiguousarray(i) for i in np.nonzero(need))  # the kernel's one signature
        w = kernels.pair_jtu(n_i, l_i, p_i, cr, unit, caps.radius_m, origins, axes, caps.anchor, qd)  # J^T u
        r, m_r = self.pair_ratios(n_i, p_i, w, approach[n_i, l_i, p_i], q, human)
        mass[n_i, l_i, p_i] = m_r
        ratio[n_i, l_i, p_i] = r

    def pair_ratios(
        self,
        n_i: np.ndarray,
        p_i: np.ndarray,
        jtu: np.ndarray,
        approach: np.ndarray,
        q: np.ndarray,
        human: HumanMotion,
        compiled: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Approach speed / v_max (K,) and the robot's effective mass (K,) [kg] of pairs at samples
        ``n_i`` toward parts ``p_i`` (K,), with their ``J^T u`` (K, n_joints) and approach speeds
        (K,) [m/s], along angles ``q`` (N, n_joints) [rad] (the arm's CRBA once per sample: Pinocchio's,
        or ``compiled``, :meth:`~.iso15066.ArmInertia.mass_matrices`)."""
        if n_i.size == 0:
            return np.empty(0), np.empty(0)
        kernels = human_kernels()
        _, force_p, m_h_p, k_p = self._region_limits(human)
        samples, which = sample_groups(n_i)
        if self._arm_inertia is None:
            self._arm_inertia = ArmInertia(self.robot)
        inertia = self._arm_inertia.mass_matrices(q[samples], compiled)
        inv = kernels.inverse_effective_masses(inertia, which.astype(np.int64), np.ascontiguousarray(jtu))
        m_r = 1.0 / np.maximum(inv, 1e-300)
        force, m_h, k = force_p[p_i], m_h_p[p_i], k_p[p_i]
        v_max = force / np.sqrt(reduced_mass_kg(m_h, m_r) * k)
        return approach / v_max, m_r
