"""What the human checks judge of the robot-body separation, computed without every pair's numbers.

``human_clearance`` and ``contact_speed`` (:mod:`ipromp_pin.safety`) judge a few reductions of the
per-sample, per-pair :class:`~.separation.Separation` (N samples x L robot capsules x P body parts):
the smallest distance to the body outside the hand and where it is, how long the robot is within
S_p, and the largest approach speed / contact-speed limit of each sample and where it is.
:func:`summarise` gives exactly these (:class:`SeparationSummary`, the same numbers as the full
separation gives them) from one pass of a compiled kernel
(:func:`~ipromp_pin.human.separation_kernels.separation_summary`) that computes a pair's distance and
approach speed only where bounds do not already settle it: the bounding spheres of the two capsules
bound the distance from below, and the velocity field of the rigid link bounds its capsule's surface
speed (so its largest possible S_p). The robot's effective masses (CRBA, Jacobian) are computed for
the pairs that need them, as :meth:`~.separation.SeparationAnalyser.analyse` computes them; the
closest sample is recomputed in full for its pair and its S_p. The body at the samples of a
planner's remaining motion is placed from its held frames (:meth:`~.body.HumanMotion.held_frames`).
``tests/human/test_separation_summary.py`` holds it to the full separation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from .body import HumanMotion
from .iso15066 import constant_distance_m
from .kernels import human_kernels
from .robot_capsules import arm_kinematics
from .separation import HAND_REGION, SeparationAnalyser, SeparationReductions


@dataclass(frozen=True)
class SeparationSummary(SeparationReductions):
    """The reductions of a :class:`~.separation.Separation` that the human checks judge.

    Attributes:
        t_s: Sample times (N,) [s].
        within_sp: (N,) whether some robot capsule is closer than S_p to some body part.
        max_ratio: (N,) the largest approach speed / v_max within S_p (0: none within S_p and fast).
        clearance_m: The smallest distance [m] to a body part outside the hand at its nominal
            position (``inf`` without such a part).
        clearance_sample: The first sample where it occurs.
        clearance_pair: (capsule, part) indices of it at that sample.
        clearance_protective_m: The smallest S_p [m] of any pair at that sample (None: none finite).
        ratio_sample: The first sample of the largest ``max_ratio``.
        ratio_pair: (capsule, part) of the largest ratio at that sample ((0, 0) when it is 0).
        worst_ratio: That ratio.
        approach_m_s: Its approach speed [m/s] (NaN when the ratio is 0).
        robot_mass_kg: The robot's effective mass [kg] there (NaN when the ratio is 0).
        protective_m: S_p [m] there (NaN when the ratio is 0).
        links: Robot capsule links (L,).
        parts: Body part names (P,).
        regions: Body regions (P,).
        human: ``"tracked"``, ``"predicted"`` or ``"assumed"`` (:attr:`.body.HumanMotion.label`).
    """

    t_s: np.ndarray
    within_sp: np.ndarray
    max_ratio: np.ndarray
    clearance_m: float
    clearance_sample: int
    clearance_pair: tuple[int, int]
    clearance_protective_m: float | None
    ratio_sample: int
    ratio_pair: tuple[int, int]
    worst_ratio: float
    approach_m_s: float
    robot_mass_kg: float
    protective_m: float
    links: tuple[str, ...]
    parts: tuple[str, ...]
    regions: tuple[str, ...]
    human: str


RATIO_RECHECK = 1e-9
"""Relative band around a deciding value in which a contact-speed ratio from the compiled CRBA is
computed again with Pinocchio's (their difference is at the rounding level, 1e-14)."""


def summarise(
    analyser: SeparationAnalyser, t: np.ndarray, q: np.ndarray, qd: np.ndarray, human: HumanMotion
) -> SeparationSummary:
    """The :class:`SeparationSummary` of a motion: times (N,) [s], angles and velocities
    (N, n_joints) [rad], [rad/s], against ``human`` (see the module docstring).

    Raises:
        DataError: a body capsule with a non-finite position or radius.
    """
    kernels = human_kernels()
    caps, s = analyser.capsules, analyser.settings
    q = np.ascontiguousarray(q, dtype=float)
    qd = np.ascontiguousarray(qd, dtype=float)
    origins, axes, ra, rb = arm_kinematics(caps, q)
    ha, hb, hr = human.capsules(t)  # C-ordered below: the kernels' one signature (the warm-up's)
    ha, hb = np.ascontiguousarray(ha), np.ascontiguousarray(hb)
    if not (np.all(np.isfinite(ha)) and np.all(np.isfinite(hb)) and np.all(np.isfinite(hr))):
        raise DataError(human.source or "human", "body capsules", "non-finite position or radius")
    hr = np.ascontiguousarray(hr)
    regions = tuple(human.regions.tolist())
    nominal = np.array([r != HAND_REGION for r in regions], dtype=np.bool_)
    body_r = np.ascontiguousarray(human.radius_m, dtype=float)
    floor = np.ascontiguousarray(analyser.contact_floor(human))
    t_r, t_stop = s.reaction_time_s, s.stopping_time_s
    sp_const = s.speed_m_s * (t_r + t_stop) + constant_distance_m(s)
    sp_per_speed = t_r + t_stop / 2.0
    clear, within, n_i, l_i, p_i, app, sp, jtu = kernels.separation_summary(
        ra, rb, caps.radius_m, ha, hb, hr, body_r, nominal, floor, origins, axes, qd, caps.anchor,
        sp_const, sp_per_speed,
    )  # fmt: skip
    ratio, mass = analyser.pair_ratios(n_i, p_i, jtu, app, q, human, compiled=True)
    n = t.size
    max_ratio = np.zeros(n)
    np.maximum.at(max_ratio, n_i, ratio)
    if n_i.size:
        # the compiled CRBA agrees with Pinocchio's to rounding (1e-14), not to the bit: where a
        # ratio decides something (the largest of the motion, a sample's against the planning limit
        # or the limit itself), its sample's pairs are computed again with Pinocchio's, so that every
        # reported number and every tie is the full separation's
        top = float(max_ratio.max())
        near = max_ratio >= top * (1.0 - RATIO_RECHECK)
        for limit in (1.0 - s.speed_margin, 1.0):
            near |= np.abs(max_ratio - limit) <= RATIO_RECHECK * limit
        redo = near[n_i]
        if np.any(redo):
            exact, exact_mass = analyser.pair_ratios(n_i[redo], p_i[redo], jtu[redo], app[redo], q, human)
            ratio[redo], mass[redo] = exact, exact_mass
            again = np.flatnonzero(near)
            max_ratio[again] = 0.0
            np.maximum.at(max_ratio, n_i[redo], exact)

    # the closest sample, in full: its pair and every pair's S_p
    nc = int(np.argmin(clear))
    one = slice(nc, nc + 1)
    dist, cr, ch = kernels.capsule_distances(ra[one], rb[one], caps.radius_m, ha[one], hb[one], hr[one])
    _, protective, _ = kernels.approach_speeds(
        dist, cr, ch, caps.radius_m, origins[one], axes[one], qd[one], caps.anchor, sp_const, sp_per_speed
    )
    d = dist[0] + (hr[one] - body_r[None, :])[0][None, :]
    d[:, ~nominal] = np.inf
    cl, cp = np.unravel_index(int(np.argmin(d)), d.shape)
    row = protective[0]
    sp_min = float(np.nanmin(row)) if np.any(np.isfinite(row)) else None

    # the fastest approach: the first sample of the largest ratio, the first pair of it there
    nr = int(np.argmax(max_ratio))
    worst = float(max_ratio[nr])
    pair, speed, m_r, sp_r = (0, 0), np.nan, np.nan, np.nan
    if worst > 0:
        at = np.flatnonzero((n_i == nr) & (ratio == worst))
        j = int(at[0])  # pairs of a sample are in (capsule, part) order
        pair = (int(l_i[j]), int(p_i[j]))
        speed, m_r, sp_r = float(app[j]), float(mass[j]), float(sp[j])
    return SeparationSummary(
        t_s=t,
        within_sp=within,
        max_ratio=max_ratio,
        clearance_m=float(d[cl, cp]),
        clearance_sample=nc,
        clearance_pair=(int(cl), int(cp)),
        clearance_protective_m=sp_min,
        ratio_sample=nr,
        ratio_pair=pair,
        worst_ratio=worst,
        approach_m_s=speed,
        robot_mass_kg=m_r,
        protective_m=sp_r,
        links=caps.links,
        parts=tuple(human.part_names.tolist()),
        regions=regions,
        human=human.label,
    )


class SeparationSummariser:
    """The summaries of one :class:`~.separation.SeparationAnalyser`'s motions, the last one kept
    (the separation checks built together share one, so that a motion is summarised once for all
    of them).

    Args:
        analyser: The separation analyser.

    Attributes:
        analyser: The separation analyser.
    """

    def __init__(self, analyser: SeparationAnalyser) -> None:
        self.analyser = analyser
        self._last: tuple[tuple, SeparationSummary] | None = None

    def summary(
        self, t_s: np.ndarray, q: np.ndarray, qd: np.ndarray, human: HumanMotion
    ) -> SeparationSummary:
        """What the human checks judge of the separation along a motion (the inputs of
        :meth:`~.separation.SeparationAnalyser.analyse`: times (N,) [s], joint angles and velocities
        (N, n_joints) [rad], [rad/s], the human): the same numbers without every pair's. The result
        for the same input objects is the last one."""
        key = (t_s, q, qd, human)
        if self._last is not None and all(a is b for a, b in zip(self._last[0], key, strict=True)):
            return self._last[1]
        result = summarise(self.analyser, np.asarray(t_s, dtype=float), q, qd, human)
        self._last = (key, result)
        return result
