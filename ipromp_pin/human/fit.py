"""Does the body model fit the demonstrations? The self-check and the registration's calibration.

The demonstrations are kinesthetic teaching: the recorded robot joints are a motion the robot really
made beside the person, so the robot was never inside the person's body. Measured against the
recorded body (the tracked skeleton's capsules, :class:`~ipromp_pin.human.HumanMotion`, in the
robot's base frame through the recording's registration), the recorded robot must stay clear of
every body part outside the hand (the hand-over contact is the hand's). Where it does not, the body
is drawn where it cannot have been: a registration off (a re-placed camera) or a body model that
does not fit the person.

* :func:`self_check` measures, in every demo with a skeleton, the recorded robot's capsules against
  the body's capsules at their nominal radii, only at samples where the part's frames were reliably
  tracked (a bridged gap is a guess, not evidence), and the tracked handing hand against the
  gripper at the hand-over (the demo's end; the hand's last reliable sample): the hand held the
  object the gripper held. A session **does not fit** when the recorded robot is inside a body part
  by more than :data:`PENETRATION_TOLERANCE_M` in any demo, or the median hand-gripper distance at
  the hand-over exceeds :data:`HAND_REACH_M`.
* :func:`calibrate` fits a rigid translation of the skeleton-to-robot registration (the tracker's
  placement), the smallest that the evidence asks for: it moves the body out of the recorded robot
  (to at most :data:`FIT_PENETRATION_M` deep) and the hand to within :data:`HAND_REACH_M` of the
  gripper; a session that fits gets no correction. Radii are never changed (the demonstrations
  bound the body from outside only: they can never prove a part thinner than its table value), and
  scale is not fitted (from the robot's clearance alone a smaller body and a closer body look the
  same, and a shrunk body would buy clearance by weakening the checks). Segment lengths are measured
  on the skeleton itself and reported with the stature they imply.

:class:`HumanFit` is the finding, stored in the model file (:meth:`HumanFit.to_json`) and applied by
:func:`registered` to every body the checks of that model's sessions judge.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..data import ROBOT, Demo
from ..exceptions import DataError
from ..robot import Robot, ee_positions
from ..robot.human_settings import HumanSettings
from ..robot.ranges import SEGMENT_FRACTIONS
from .body import HumanMotion
from .kernels import human_kernels
from .robot_capsules import RobotCapsules, arm_kinematics, fit_robot_capsules

PENETRATION_TOLERANCE_M = 0.02
"""How deep [m] the recorded robot may be inside the recorded body before the session does not fit:
the robot's capsules enclose its links (they over-state the robot by up to about 1 cm) and a
depth-camera skeleton tracker places its joint centres within about 1-2 cm; a shallower overlap is
within the model's own error."""

FIT_PENETRATION_M = 0.01
"""The calibration moves the body until the recorded robot is at most this deep [m] in it (it aims
:data:`FIT_MARGIN_M` inside: the optimiser stops at the boundary of a one-sided cost, on either
side of it)."""

HAND_REACH_M = 0.15
"""Largest median distance [m] between the tracked handing hand (the tracker's hand joint, at the
palm) and the gripper frame at the hand-over for a body that fits: the hand's sphere (10 cm, half a
95th-percentile hand length) plus 5 cm of the held object between the palm and the gripper frame."""

FIT_MARGIN_M = 0.002
"""How far [m] inside :data:`FIT_PENETRATION_M` and :data:`HAND_REACH_M` the calibration aims."""

HANDING_HAND = "/left_hand_1"
"""The tracked frame of the handing hand (OpenNI's mirrored label of the person's right hand)."""

STEP = 2
"""Every STEP-th sample of a demo is measured (50 Hz recordings: every 40 ms)."""

MAX_CORRECTION_M = 0.25
"""Largest registration correction [m] the calibration makes: a larger error is no camera nudged
out of place, and the session is reported as not fitting instead."""

FIT_VERSION = 1
"""Version of :meth:`HumanFit.to_json`'s layout."""


@dataclass(frozen=True)
class Registration:
    """A rigid correction of the skeleton-to-robot registration: ``p' = p + translation_m``.

    Attributes:
        translation_m: (3,) [m] in the robot's base frame.
    """

    translation_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def is_identity(self) -> bool:
        """Whether the correction changes nothing."""
        return not any(self.translation_m)

    def apply(self, positions_m: np.ndarray) -> np.ndarray:
        """Positions (..., 3) [m] corrected (NaN stays NaN)."""
        return np.asarray(positions_m, dtype=float) + np.asarray(self.translation_m)


@dataclass(frozen=True)
class PartFinding:
    """The recorded robot inside one body part.

    Attributes:
        part: Body part name.
        n_demos: Demos in which the robot is inside it beyond the tolerance.
        depth_m: The deepest penetration [m] over all demos (> 0: inside).
    """

    part: str
    n_demos: int
    depth_m: float


@dataclass(frozen=True)
class FitMeasures:
    """The self-check's measures of one registration over the measured demos.

    Attributes:
        n_demos: Demos measured (with a skeleton).
        n_inside: Demos where the recorded robot is inside the body beyond the tolerance.
        worst_clearance_m: Smallest clearance [m] over the demos (negative: inside).
        median_clearance_m: Median over the demos of each demo's smallest clearance [m].
        hand_reach_m: Median hand-gripper distance [m] at the hand-over (NaN: never tracked).
        parts: Per body part with a demo inside it beyond the tolerance.
    """

    n_demos: int
    n_inside: int
    worst_clearance_m: float
    median_clearance_m: float
    hand_reach_m: float
    parts: tuple[PartFinding, ...] = ()

    @property
    def fits(self) -> bool:
        """Whether the body fits: nowhere inside beyond the tolerance, the hand within reach."""
        reach_ok = not math.isfinite(self.hand_reach_m) or self.hand_reach_m <= HAND_REACH_M
        return self.n_inside == 0 and reach_ok

    def problems(self) -> list[str]:
        """One phrase per misfit (empty when it fits)."""
        out = [
            f"the demonstrated robot is {p.depth_m * 100:.1f} cm inside the {p.part} "
            f"({p.n_demos} of {self.n_demos} demos beyond {PENETRATION_TOLERANCE_M * 100:g} cm)"
            for p in self.parts
        ]
        if math.isfinite(self.hand_reach_m) and self.hand_reach_m > HAND_REACH_M:
            out.append(
                f"the tracked hand is {self.hand_reach_m * 100:.1f} cm from the gripper at the hand-over "
                f"(median; at most {HAND_REACH_M * 100:g} cm when it holds the object)"
            )
        return out

    def to_json(self) -> dict:
        """JSON-serialisable form."""
        return {
            "n_demos": self.n_demos,
            "n_inside": self.n_inside,
            "worst_clearance_m": _num(self.worst_clearance_m),
            "median_clearance_m": _num(self.median_clearance_m),
            "hand_reach_m": _num(self.hand_reach_m),
            "parts": [[p.part, p.n_demos, p.depth_m] for p in self.parts],
        }

    @classmethod
    def from_json(cls, d: dict) -> FitMeasures:
        """The measures of :meth:`to_json`."""
        return cls(
            int(d["n_demos"]),
            int(d["n_inside"]),
            _float(d["worst_clearance_m"]),
            _float(d["median_clearance_m"]),
            _float(d["hand_reach_m"]),
            tuple(PartFinding(str(p), int(n), float(x)) for p, n, x in d["parts"]),
        )


@dataclass(frozen=True)
class HumanFit:
    """The self-check of a session's body model and its calibration (see the module docstring).

    Attributes:
        recorded: Measures with the recording's own registration.
        registration: The fitted correction (identity when the recording fits).
        calibrated: Measures with the correction applied (the residuals).
        segments_m: Body part -> median tracked length [m] between its frames.
        stature_m: Median stature [m] the segment lengths imply (NaN: none measured).
        refused: One error per demo whose skeleton the body model refused (not measured).
    """

    recorded: FitMeasures
    registration: Registration = Registration()
    calibrated: FitMeasures | None = None
    segments_m: dict[str, float] = field(default_factory=dict)
    stature_m: float = math.nan
    refused: tuple[str, ...] = ()

    @property
    def fits(self) -> bool:
        """Whether the body model as the checks use it (calibrated) fits the demonstrations."""
        return (self.calibrated or self.recorded).fits

    def to_json(self) -> dict:
        """JSON-serialisable form (the model file's header ``human_fit``)."""
        return {
            "version": FIT_VERSION,
            "recorded": self.recorded.to_json(),
            "translation_m": list(self.registration.translation_m),
            "calibrated": None if self.calibrated is None else self.calibrated.to_json(),
            "segments_m": dict(self.segments_m),
            "stature_m": _num(self.stature_m),
            "refused": list(self.refused),
        }

    @classmethod
    def from_json(cls, d: dict, source: str = "model file") -> HumanFit:
        """The fit of :meth:`to_json`.

        Raises:
            DataError: a malformed entry (naming ``source`` and the field).
        """
        try:
            t = [float(x) for x in d["translation_m"]]
            if len(t) != 3 or not all(math.isfinite(x) and abs(x) < 10.0 for x in t):
                raise ValueError(f"translation {t} is not 3 finite values within 10 m")
            return cls(
                FitMeasures.from_json(d["recorded"]),
                Registration((t[0], t[1], t[2])),
                None if d["calibrated"] is None else FitMeasures.from_json(d["calibrated"]),
                {str(k): float(v) for k, v in d["segments_m"].items()},
                _float(d["stature_m"]),
                tuple(str(x) for x in d.get("refused", [])),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(source, "human_fit", f"malformed human model fit ({exc})") from None

    def summary(self) -> list[str]:
        """Report lines: the finding, the fitted correction and its residuals."""
        r = self.recorded
        lines = [
            f"human model self-check on {r.n_demos} demos with a skeleton: demonstrated robot inside the "
            f"body beyond {PENETRATION_TOLERANCE_M * 100:g} cm in {r.n_inside} demos; clearance worst "
            f"{r.worst_clearance_m * 100:.1f} cm, median {r.median_clearance_m * 100:.1f} cm; hand to "
            f"gripper at the hand-over {r.hand_reach_m * 100:.1f} cm (median): "
            + ("fits" if r.fits else "DOES NOT FIT")
        ]
        lines += [f"  {p}" for p in r.problems()]
        if self.refused:
            lines.append(
                f"  {len(self.refused)} demos not measured, their skeleton refused (first: {self.refused[0]})"
            )
        if math.isfinite(self.stature_m):
            seg = ", ".join(f"{k} {v * 100:.1f}" for k, v in self.segments_m.items())
            lines.append(
                f"  segment lengths [cm] {seg}; implied stature {self.stature_m:.2f} m (radii unchanged)"
            )
        c = self.calibrated
        if c is not None and not self.registration.is_identity:
            t = ", ".join(f"{x * 100:+.1f}" for x in self.registration.translation_m)
            lines.append(
                f"  registration corrected by [{t}] cm: inside beyond {PENETRATION_TOLERANCE_M * 100:g} cm "
                f"in "
                f"{c.n_inside} demos; clearance worst {c.worst_clearance_m * 100:.1f} cm, median "
                f"{c.median_clearance_m * 100:.1f} cm; hand to gripper {c.hand_reach_m * 100:.1f} cm: "
                + ("fits" if c.fits else "still DOES NOT FIT")
            )
        return lines


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _float(x: object) -> float:
    return math.nan if x is None else float(x)  # type: ignore[arg-type]


def registration_of(record: Mapping[str, Any] | None, source: str = "model") -> Registration | None:
    """The registration correction of a model's ``human_fit`` record (None: not measured)."""
    return None if record is None else HumanFit.from_json(dict(record), source).registration


def registered(human: HumanMotion, registration: Registration | None) -> HumanMotion:
    """``human`` with its tracked frames moved by ``registration`` (the same object when there is
    nothing to move: no correction, or the assumed human, which the settings place)."""
    if registration is None or registration.is_identity or human.assumed:
        return human
    return replace(human, positions_m=registration.apply(human.positions_m))


# --------------------------------------------------------------------------------------------------
# Evidence and measures
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DemoEvidence:
    """What one demo proves about the body: the recorded robot's capsules at the measured samples,
    the body there, and the gripper at the hand-over.

    Attributes:
        human: The recorded body (the recording's registration).
        t_s: Measured sample times (N,) [s].
        ra: Robot capsule first ends (N, L, 3) [m].
        rb: Robot capsule second ends (N, L, 3) [m].
        gripper_m: The gripper at the hand-over (3,) [m].
        caps_radius: Robot capsule radii (L,) [m].
    """

    human: HumanMotion
    t_s: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    gripper_m: np.ndarray
    caps_radius: np.ndarray


def demo_evidence(
    demos: Sequence[Demo],
    robot: Robot,
    settings: HumanSettings | None = None,
    refused: list[str] | None = None,
) -> list[DemoEvidence]:
    """The evidence of every demo with a tracked skeleton (none: an empty list). A demo whose
    skeleton the body model refuses (:meth:`~ipromp_pin.human.HumanMotion.from_demo`: a frame never
    tracked, an impossible segment) is left out, its error appended to ``refused`` when given."""
    settings = settings if settings is not None else robot.settings.human
    caps: RobotCapsules | None = None
    out = []
    for demo in demos:
        try:
            human = HumanMotion.from_demo(demo, settings)
        except DataError as exc:
            if refused is not None:
                refused.append(str(exc))
            continue
        if human is None or ROBOT not in demo.groups:
            continue
        caps = caps if caps is not None else fit_robot_capsules(robot)
        q = np.asarray(demo.groups[ROBOT], dtype=float)
        idx = np.arange(0, q.shape[0], STEP)
        _, _, ra, rb = arm_kinematics(caps, q[idx])
        gripper = ee_positions(robot, q[-1:])[0]
        out.append(DemoEvidence(human, demo.t[idx], ra, rb, gripper, caps.radius_m))
    return out


@dataclass(frozen=True)
class _Samples:
    """The measured samples of every demo, stacked, with the body's capsules computed once: a
    registration correction is a translation, which moves every capsule end (an average of frames)
    by itself, so each measure only adds it.

    Attributes:
        ra, rb: Recorded robot capsule ends (N, L, 3) [m]; ``caps_radius`` (L,) their radii.
        ha, hb: Body capsule ends outside the hand (N, P', 3) [m] at the recording's registration.
        hr: Their radii (N, P') [m].
        reliable: (N, P') whether the part's frames were reliably tracked at the sample.
        demo: (N,) the index of every sample's demo, ascending.
        hand_m: (D, 3) each demo's handing hand at its last reliable sample [m] (NaN: none).
        gripper_m: (D, 3) each demo's gripper at the hand-over [m].
    """

    ra: np.ndarray
    rb: np.ndarray
    caps_radius: np.ndarray
    ha: np.ndarray
    hb: np.ndarray
    hr: np.ndarray
    reliable: np.ndarray
    demo: np.ndarray
    hand_m: np.ndarray
    gripper_m: np.ndarray

    @property
    def n_demos(self) -> int:
        return int(self.gripper_m.shape[0])

    def sample_clearances(self, shift: np.ndarray) -> np.ndarray:
        """Per sample and body part outside the hand (N, P') the recorded robot's clearance [m] with
        the body moved by ``shift`` (3,) [m]; inf where the part was not reliably tracked."""
        dist, _, _ = human_kernels().capsule_distances(
            self.ra, self.rb, self.caps_radius, self.ha + shift, self.hb + shift, self.hr
        )
        return np.where(self.reliable, dist.min(axis=1), np.inf)

    def part_clearances(self, shift: np.ndarray) -> np.ndarray:
        """Per demo and body part outside the hand (D, P') the smallest clearance [m] over the
        demo's samples where the part was reliably tracked (inf: never)."""
        per = np.full((self.n_demos, self.ha.shape[1]), np.inf)
        if self.demo.size:
            which, first = np.unique(self.demo, return_index=True)
            per[which] = np.minimum.reduceat(self.sample_clearances(shift), first, axis=0)
        return per

    def hand_reach(self, shift: np.ndarray) -> np.ndarray:
        """Per demo (D,) the distance [m] from the gripper at the hand-over to the handing hand's last
        reliable position moved by ``shift`` (NaN: no hand)."""
        return np.linalg.norm(self.gripper_m - (self.hand_m + shift), axis=1)

    def where(self, keep: np.ndarray) -> _Samples:
        """The samples where ``keep`` (N,) holds, every demo kept."""
        return replace(
            self,
            ra=self.ra[keep],
            rb=self.rb[keep],
            ha=self.ha[keep],
            hb=self.hb[keep],
            hr=self.hr[keep],
            reliable=self.reliable[keep],
            demo=self.demo[keep],
        )


def _body_capsules(ev: DemoEvidence) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One demo's body at its measured samples: capsule ends outside the hand (N, P', 3) [m], their
    radii (N, P') [m] and whether their frames were reliably tracked (N, P')."""
    h = ev.human
    t_idx = np.clip(np.searchsorted(h.t_s, ev.t_s), 0, h.t_s.size - 1)
    frames = h.positions_m[t_idx]  # (N, F, 3), NaN where not reliable
    wa, wb, ma, mb, trim = h._parts  # type: ignore[attr-defined]
    ok = np.all(np.isfinite(frames), axis=2)  # (N, F)
    member = np.maximum(ma, mb) > 0  # (P, F)
    reliable = ~np.any(member[None] & ~ok[:, None, :], axis=2)  # (N, P)
    filled = np.nan_to_num(frames)
    a = np.einsum("pf,nfc->npc", wa, filled)
    b = np.einsum("pf,nfc->npc", wb, filled)
    if np.any(trim > 0):
        axis = b - a
        length = np.linalg.norm(axis, axis=2, keepdims=True)
        keep = np.maximum(length - trim[None, :, None], 0.0) / np.maximum(length, 1e-12)
        b = np.where(trim[None, :, None] > 0, a + axis * keep, b)
    out = h.regions != "hand"
    hr = np.broadcast_to(h.radius_m, reliable.shape)
    return a[:, out], b[:, out], np.ascontiguousarray(hr[:, out]), reliable[:, out]


def _last_hand(ev: DemoEvidence) -> np.ndarray:
    """The handing hand's last reliable position (3,) [m] (NaN: no hand tracked)."""
    h = ev.human
    if HANDING_HAND not in h.frames:
        return np.full(3, np.nan)
    hand = h.positions_m[:, h.frames.index(HANDING_HAND)]
    ok = np.flatnonzero(np.all(np.isfinite(hand), axis=1))
    return hand[ok[-1]] if ok.size else np.full(3, np.nan)


def _samples(evidence: Sequence[DemoEvidence]) -> _Samples:
    """The demos' ``evidence`` stacked (its body parts must be the same model's)."""
    if not evidence:
        raise ValueError("no demo with a skeleton to measure")
    parts = {tuple(ev.human.part_names) for ev in evidence}
    if len(parts) > 1:
        raise ValueError("the demos' evidence holds bodies of different part lists")
    ha, hb, hr, reliable = (np.concatenate(x) for x in zip(*map(_body_capsules, evidence), strict=True))
    return _Samples(
        ra=np.concatenate([ev.ra for ev in evidence]),
        rb=np.concatenate([ev.rb for ev in evidence]),
        caps_radius=evidence[0].caps_radius,
        ha=ha,
        hb=hb,
        hr=hr,
        reliable=reliable,
        demo=np.repeat(np.arange(len(evidence)), [ev.t_s.size for ev in evidence]),
        hand_m=np.array([_last_hand(ev) for ev in evidence]),
        gripper_m=np.array([ev.gripper_m for ev in evidence]),
    )


def _near(samples: _Samples) -> _Samples:
    """The samples where the recorded robot comes within :data:`MAX_CORRECTION_M` + 5 cm of the
    recorded body: a correction of at most :data:`MAX_CORRECTION_M` cannot bring another sample
    inside (a distance changes at most as much as the body moves)."""
    return samples.where(samples.sample_clearances(np.zeros(3)).min(axis=1) < MAX_CORRECTION_M + 0.05)


def measure(evidence: Sequence[DemoEvidence], registration: Registration = Registration()) -> FitMeasures:
    """The self-check's measures of the demos' ``evidence`` with ``registration`` applied."""
    return _measure(_samples(evidence), evidence[0].human, registration)


def _measure(
    samples: _Samples, body: HumanMotion, registration: Registration = Registration()
) -> FitMeasures:
    """:func:`measure` of the stacked ``samples`` (``body``: any of their demos' body, for its parts)."""
    shift = np.asarray(registration.translation_m, dtype=float)
    per = samples.part_clearances(shift)  # (D, P')
    names = [str(n) for n, r in zip(body.part_names, body.regions, strict=True) if r != "hand"]
    worst = per.min(axis=1)
    inside = worst < -PENETRATION_TOLERANCE_M
    parts = []
    for k, name in enumerate(names):
        deep = per[:, k] < -PENETRATION_TOLERANCE_M
        if deep.any():
            parts.append(PartFinding(name, int(deep.sum()), float(-per[:, k].min())))
    parts.sort(key=lambda p: -p.depth_m)
    reach = samples.hand_reach(shift)
    finite = worst[np.isfinite(worst)]
    return FitMeasures(
        samples.n_demos,
        int(inside.sum()),
        float(finite.min()) if finite.size else math.nan,
        float(np.median(finite)) if finite.size else math.nan,
        float(np.nanmedian(reach)) if np.isfinite(reach).any() else math.nan,
        tuple(parts),
    )


def segment_lengths(evidence: Sequence[DemoEvidence]) -> tuple[dict[str, float], float]:
    """Median tracked length [m] of every capsule part with an anthropometric fraction, and the
    median stature [m] they imply (length / fraction of stature)."""
    out: dict[str, float] = {}
    statures = []
    for k, part in enumerate(evidence[0].human.parts):
        if part.b is None or part.name not in SEGMENT_FRACTIONS:
            continue
        lengths = []
        for ev in evidence:
            h = ev.human
            wa, wb = h._parts[0][k], h._parts[1][k]  # type: ignore[attr-defined]
            with np.errstate(invalid="ignore"):
                d = np.linalg.norm(np.einsum("f,tfc->tc", wa - wb, h.positions_m), axis=1)
            lengths.append(d[np.isfinite(d)])
        both = np.concatenate(lengths)
        if both.size:
            out[part.name] = float(np.median(both))
            statures.append(out[part.name] / SEGMENT_FRACTIONS[part.name])
    return out, float(np.median(statures)) if statures else math.nan


# --------------------------------------------------------------------------------------------------
# The calibration
# --------------------------------------------------------------------------------------------------


def _cost(samples: _Samples, shift: np.ndarray) -> float:
    """The calibration's cost [m^2] of moving the body by ``shift`` (3,) [m]: penetrations beyond
    :data:`FIT_PENETRATION_M` (mean over the demos, squared), the hand beyond reach (squared), and
    the size of the move (the smallest correction the evidence asks for)."""
    norm = float(np.linalg.norm(shift))
    if norm > MAX_CORRECTION_M:
        return 1.0 + norm
    worst = samples.part_clearances(shift).min(axis=1)  # (D,), inf: a demo never near
    pen = float(np.sum(np.maximum(-worst - (FIT_PENETRATION_M - FIT_MARGIN_M), 0.0) ** 2))
    reach = samples.hand_reach(shift)
    goal = HAND_REACH_M - FIT_MARGIN_M
    over = max(float(np.nanmedian(reach)) - goal, 0.0) if np.isfinite(reach).any() else 0.0
    return 100.0 * pen / samples.n_demos + 100.0 * over**2 + 1e-3 * norm**2


def calibrate(evidence: Sequence[DemoEvidence]) -> Registration:
    """The smallest translation of the registration that the evidence asks for, at most
    :data:`MAX_CORRECTION_M` (identity when the recording fits; see the module docstring)."""
    samples = _samples(evidence)
    if _measure(samples, evidence[0].human).fits:
        return Registration()
    return _fitted_translation(samples)


def _fitted_translation(samples: _Samples) -> Registration:
    """:func:`calibrate`'s translation for stacked ``samples`` that do not fit as recorded."""
    from scipy.optimize import minimize

    near = _near(samples)
    res = minimize(
        lambda x: _cost(near, x),
        np.zeros(3),
        method="Nelder-Mead",
        options={
            "xatol": 5e-4,
            "fatol": 1e-10,
            "maxfev": 400,
            "initial_simplex": 0.05 * np.vstack([np.zeros(3), np.eye(3)]),
        },
    )
    best = np.asarray(res.x, dtype=float) if res.fun < _cost(near, np.zeros(3)) else np.zeros(3)
    t = np.round(best, 4)
    return Registration((float(t[0]), float(t[1]), float(t[2])))


def self_check(
    demos: Sequence[Demo], robot: Robot, settings: HumanSettings | None = None, fit: bool = True
) -> HumanFit | None:
    """The self-check of the demos' body model and (``fit``) the calibrated registration; None when
    no demo has a tracked skeleton (not measured)."""
    refused: list[str] = []
    evidence = demo_evidence(demos, robot, settings, refused)
    if not evidence:
        return None
    samples, body = _samples(evidence), evidence[0].human  # stacked once for every measure below
    recorded = _measure(samples, body)
    segments, stature = segment_lengths(evidence)
    if not fit or recorded.fits:
        return HumanFit(recorded, Registration(), None, segments, stature, tuple(refused))
    reg = _fitted_translation(samples)
    return HumanFit(recorded, reg, _measure(samples, body, reg), segments, stature, tuple(refused))
