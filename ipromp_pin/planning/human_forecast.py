"""The predicted human: calibrate the body's forecast on training demos, use it in a plan.

:func:`calibrate` measures, by cross-validation over the training demos, how far the model's
prediction of its observed hand frame (and of the body moving with it, :mod:`ipromp_pin.human.forecast`)
can be trusted at each look-ahead; :func:`predicted_human` gives a plan's checks the human as
observed, with every tracked frame placed by the prediction wherever that is a tighter bound than
holding it. A model without a calibration (no observed hand frame, no tracked skeleton in its demos, a model
file before format version 8) plans against the held body as before.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..data import Demo
from ..exceptions import IPrompPinError
from ..human.body import HumanMotion
from ..human.forecast import HAND_FRAMES, ForecastCalibration, fit_gains, forecast_body, quantile_radii
from ..promp import IProMP, Prediction
from ..promp.inputs import ObservationWarning
from ..robot.human_settings import HumanSettings
from ..safety import CheckContext

QUANTILE = 0.95
"""Quantile of the cross-validated forecast errors the radii take (one in 20 held-out forecasts
farther at that look-ahead)."""

FOLDS = 3
"""Folds of the calibration's cross-validation (stratified by task, by demo order)."""

RATIOS = (0.1, 0.25, 0.4, 0.55, 0.7)
"""Observed fractions of each held-out demo the forecast is measured from."""

LOOKAHEAD_GRID_S = np.round(np.arange(0.0, 3.01, 0.1), 10)
"""Look-ahead grid [s] of the radii."""

TRUST_WINDOW_S = 0.2
"""The trust test compares the predicted and the observed hand's displacement over the last
``TRUST_WINDOW_S`` [s] before the last observation."""

MIN_COUNT = 30
"""Fewest errors a look-ahead bin needs; the calibration ends before the first bin with fewer."""

MIN_DEMOS = 10
"""Fewest training demos with a tracked skeleton a calibration is made from."""

GAIN_LAGS_S = (0.2, 0.5, 1.0)
"""Lags [s] of the displacement pairs the frames' gains are fitted on."""


@dataclass(frozen=True)
class _Body:
    """A demo's recorded body and its frame positions (T, F, 3) [m] at its times (NaN: not tracked),
    the calibration's frames in their order."""

    body: HumanMotion
    positions_m: np.ndarray


def forecast_group(model: IProMP, settings: HumanSettings) -> str | None:
    """The body model's hand frame (one of :data:`HAND_FRAMES`) that one of the model's observed
    groups tracks, through the settings' skeleton map; None when none does."""
    mapped = settings.skeleton.body_frames()
    for group in model.observe_:
        for hand in HAND_FRAMES:
            if mapped.get(hand, (hand,)) == (group,):
                return hand
    return None


def forecast_of(
    model: IProMP, settings: HumanSettings | None = None, source: str = "model"
) -> ForecastCalibration | None:
    """The model's forecast calibration (None: none stored, or the settings' ``handing_arm`` is
    ``"held"``).

    Raises:
        DataError: a malformed record (naming ``source``).
    """
    record = getattr(model, "human_forecast_", None)
    if settings is not None and settings.handing_arm == "held":
        return None
    return None if record is None else ForecastCalibration.from_json(record, source)


def with_forecast(model: IProMP, demos: Sequence[Demo], settings: HumanSettings | None = None) -> IProMP:
    """``model`` (fitted on ``demos``) with the body's forecast calibrated on them
    (:func:`calibrate`; its record None when there is none)."""
    cal = calibrate(model, demos, settings)
    return model.with_human_forecast(None if cal is None else cal.to_json())


def forecast_summary(cal: ForecastCalibration | None) -> str:
    """One line on the calibration, for the console."""
    if cal is None:
        return (
            "body forecast: none (the robot settings' handing_arm is held, the model observes no tracked "
            "hand frame, or too few demos have a skeleton): plans hold the body where last seen"
        )
    look = cal.lookahead_s
    at = [k for k in (0.5, 1.0) if k <= look[-1]]

    def radii(rows: np.ndarray) -> str:
        return " / ".join(f"{np.median([np.interp(k, look, r) for r in rows]) * 100:.1f}" for k in at)

    when = " / ".join(f"{k:g}" for k in at)
    return (
        f"body forecast from {cal.group}: {cal.quantile:.0%} error radius at {when} s ahead: hand "
        f"{radii(cal.radius_m[:1])} cm, the other {len(cal.frames) - 1} frames (median) "
        f"{radii(cal.radius_m[1:])} cm; cross-validated on {cal.n_demos} demos ({cal.n_forecasts} "
        f"forecasts), up to {look[-1]:g} s ahead"
    )


def calibrate(
    model: IProMP, demos: Sequence[Demo], settings: HumanSettings | None = None
) -> ForecastCalibration | None:
    """The forecast calibration of ``model`` from its training ``demos`` (module docstring); None
    when the settings hold the body (``handing_arm = "held"``), the model observes no hand frame or
    fewer than :data:`MIN_DEMOS` demos have a tracked skeleton with the hand (then plans hold the
    body as observed)."""
    settings = settings if settings is not None else HumanSettings()
    hand = forecast_group(model, settings)
    if hand is None or settings.handing_arm == "held":  # held: no forecast is used, none is made
        return None
    group = settings.skeleton.body_frames().get(hand, (hand,))[0]
    frames = (hand, *(f for f in HumanMotion.body_frames() if f != hand))
    bodies: list[_Body | None] = [_body(d, frames, settings) for d in demos]
    usable = [i for i, b in enumerate(bodies) if b is not None]
    if len(usable) < MIN_DEMOS:
        return None
    errors: list[np.ndarray] = []
    looks: list[np.ndarray] = []
    offsets: list[np.ndarray] = []
    for train, test in _folds(demos, usable):
        gains = _gains([b for i in train if (b := bodies[i]) is not None])
        try:
            fold = IProMP(**_fixed_params(model)).fit([demos[i] for i in train])
        except IPrompPinError:
            continue
        for i in test:
            body = bodies[i]
            assert body is not None
            for e, lk, off in _measure(fold, demos[i], body, group, gains, frames):
                errors.append(e)
                looks.append(lk)
                offsets.append(off)
    if not offsets:
        return None
    per_forecast = np.stack([o[0] for o in offsets])  # (n, F): one set of trust residuals per forecast
    offset_m = np.array([_quantile(per_forecast[:, j]) for j in range(len(frames))])
    off = np.concatenate(offsets)  # (N, F)
    # what a plan uses: forecasts whose hand follows the prediction, frames whose motion does
    trusted = (off <= offset_m[None, :]) & (off[:, :1] <= offset_m[0])
    err = np.where(trusted, np.concatenate(errors), np.nan)  # (N, F), NaN: not tracked or not trusted
    look = np.concatenate(looks)
    radii = np.stack(
        [
            quantile_radii(err[:, j], look[:, j], LOOKAHEAD_GRID_S, QUANTILE, MIN_COUNT)
            for j in range(len(frames))
        ]
    )
    keep = np.isfinite(radii[:, 1]) & np.isfinite(offset_m)  # frames with evidence one step ahead
    if not keep[0]:
        return None
    frames = tuple(f for f, k in zip(frames, keep, strict=True) if k)
    radii = radii[keep]
    finite = np.all(np.isfinite(radii), axis=0)
    n_ok = radii.shape[1] if np.all(finite) else int(np.argmin(finite))
    if n_ok < 2:
        return None
    gains_all = _gains([b for b in bodies if b is not None])[keep]
    return ForecastCalibration(
        group, frames, gains_all, LOOKAHEAD_GRID_S[:n_ok].copy(), radii[:, :n_ok].copy(), offset_m[keep],
        QUANTILE, len(usable), int(np.sum(per_forecast[:, 0] <= offset_m[0])),
    )  # fmt: skip


def _quantile(x: np.ndarray) -> float:
    """The :data:`QUANTILE` of the finite values of ``x`` (NaN when fewer than :data:`MIN_COUNT`)."""
    x = x[np.isfinite(x)]
    return float(np.quantile(x, QUANTILE)) if x.size >= MIN_COUNT else float("nan")


def predicted_human(
    human: HumanMotion | None, prediction: Prediction, calibration: ForecastCalibration | None
) -> HumanMotion | None:
    """``human`` (as known at its horizon) with its frames placed by ``prediction`` after the horizon
    where the calibration trusts them (module docstring); ``human`` itself when there is no
    calibration, the task is unknown, the human is assumed, its hand was not seen or the predicted
    hand does not follow the observed one."""
    if calibration is None or human is None or human.assumed or not prediction.known:
        return human
    hand = prediction.human_mean.get(calibration.group)
    if hand is None:
        return human
    anchors, anchor_s = human.last_seen(calibration.frames)
    frames = calibration.frames
    residual = trust_residuals(human, frames, calibration.gains, prediction.t, hand, anchors, anchor_s)
    if not residual[0] <= calibration.offset_m[0]:  # the predicted hand does not follow the observed one
        return human
    untrusted = ~(residual <= calibration.offset_m)  # a frame moving unlike the training demos: held
    anchors[untrusted], anchor_s[untrusted] = np.nan, np.nan
    return human.with_forecast(forecast_body(calibration, prediction.t, hand, anchors, anchor_s))


def replan_context(
    context: CheckContext,
    prediction: Prediction,
    observed_until_s: float,
    calibration: ForecastCalibration | None,
) -> CheckContext:
    """What a closed-loop re-plan's checks know: ``context`` with the predicted task and hand-over
    time, the human as observed until ``observed_until_s`` [s] with the handing arm as predicted
    (:func:`predicted_human`)."""
    context = context.replace(task=prediction.task, handover_s=float(prediction.duration_s))
    if context.human is None:
        return context
    human = context.human.until(observed_until_s)
    return context.replace(human=predicted_human(human, prediction, calibration))


def trust_residuals(
    human: HumanMotion,
    frames: tuple[str, ...],
    gains: np.ndarray,
    t_pred: np.ndarray,
    hand_pred: np.ndarray,
    anchors: np.ndarray,
    anchor_s: np.ndarray,
) -> np.ndarray:
    """Per frame of ``frames`` (F,) [m]: how far its observed displacement over the
    :data:`TRUST_WINDOW_S` before it was last seen (``anchors`` (F, 3) [m] at ``anchor_s`` (F,) [s])
    differs from the one the prediction gives it (``gains[f]`` (3, 3) times the predicted hand's,
    ``hand_pred`` (M, 3) [m] at ``t_pred`` (M,) [s]); NaN where the frame was not seen at both ends."""
    out = np.full(len(frames), np.nan)
    seen = np.flatnonzero(np.isfinite(anchor_s))
    if seen.size == 0:
        return out
    starts = anchor_s[seen] - TRUST_WINDOW_S
    times, row = np.unique(starts, return_inverse=True)  # most frames were last seen together
    pos, _ = human.frames_at(times)  # (U, F_body, 3)
    before = pos[row, [human.frames.index(frames[j]) for j in seen]]  # (n, 3): each at its start
    ends = np.concatenate([starts, anchor_s[seen]])
    mu = np.stack([np.interp(ends, t_pred, hand_pred[:, c]) for c in range(3)], axis=1)
    moved = mu[seen.size :] - mu[: seen.size]  # (n, 3): the predicted hand over each window
    predicted = (gains[seen] @ moved[:, :, None])[:, :, 0]
    out[seen] = np.linalg.norm((anchors[seen] - before) - predicted, axis=1)
    return out


def _body(demo: Demo, frames: tuple[str, ...], settings: HumanSettings) -> _Body | None:
    """The demo's tracked body in the order of ``frames`` (None without a skeleton, with one the body
    model refuses, or without the hand)."""
    try:
        body = HumanMotion.from_demo(demo, settings)
    except IPrompPinError:
        return None
    if body is None or frames[0] not in body.frames:
        return None
    pos = np.full((body.t_s.size, len(frames), 3), np.nan)
    for j, f in enumerate(frames):
        if f in body.frames:
            pos[:, j] = body.positions_m[:, body.frames.index(f)]
    return _Body(body, pos)


def _folds(demos: Sequence[Demo], usable: list[int]) -> list[tuple[list[int], list[int]]]:
    """:data:`FOLDS` folds: every demo trains in the others; the usable ones are tested in theirs."""
    fold_of: dict[int, int] = {}
    count: dict[str, int] = {}
    for i, d in enumerate(demos):
        k = count.get(d.task, 0)
        fold_of[i] = k % FOLDS
        count[d.task] = k + 1
    out = []
    for k in range(FOLDS):
        train = [i for i in range(len(demos)) if fold_of[i] != k]
        test = [i for i in usable if fold_of[i] == k]
        if test and len({demos[i].task for i in train}) == len(count):
            out.append((train, test))
    return out


def _fixed_params(model: IProMP) -> dict:
    """The model's parameters with its cross-validated choices fixed (a fold's fit repeats no
    selection), without the hand-over estimates (the forecast uses the human channels only) and
    without the recognition head and the novelty detector (a fold recognises by the generative
    posterior: its misrecognised forecasts count in the errors, which can only widen the radii)."""
    p = model.get_params()
    p.update(
        noise=model.noise_ratio_,
        temperature=model.temperature_,
        condition_noise=model.condition_noise_ratio_,
        coupling=list(model.coupled_groups_) or "all",
        handover=False,
        head=False,
        novelty_alpha=None,
    )
    return p


def _gains(bodies: list[_Body]) -> np.ndarray:
    """Each frame's displacement gain (F, 3, 3) against the hand's (the identity for the hand;
    zero for a frame never tracked with it)."""
    n_f = bodies[0].positions_m.shape[1]
    pairs: list[np.ndarray] = []
    for b in bodies:
        dt = float(np.median(np.diff(b.body.t_s)))
        for lag in GAIN_LAGS_S:
            k = int(round(lag / dt))
            if 0 < k < b.body.t_s.size:
                pairs.append(b.positions_m[k:] - b.positions_m[:-k])  # (T-k, F, 3)
    d = np.concatenate(pairs)
    gains = np.zeros((n_f, 3, 3))
    gains[0] = np.eye(3)
    hand_ok = np.all(np.isfinite(d[:, 0]), axis=1)
    for j in range(1, n_f):
        ok = hand_ok & np.all(np.isfinite(d[:, j]), axis=1)
        if np.count_nonzero(ok) >= 10:
            gains[j] = fit_gains(d[ok, 0], d[ok, j])
    return gains


def _measure(
    model: IProMP, demo: Demo, rec: _Body, group: str, gains: np.ndarray, frames: tuple[str, ...]
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per observed fraction of ``demo``: the forecast errors (N, F) [m] at the demo's later samples,
    their look-aheads (N, F) [s] and the frames' trust residuals (:func:`trust_residuals`),
    repeated (N, F) [m]."""
    out = []
    n_f = len(frames)
    unit = ForecastCalibration(
        group, frames, gains, np.array([0.0, 1.0]), np.zeros((n_f, 2)), np.zeros(n_f), 0.5, 0, 0
    )
    for ratio in RATIOS:
        obs = demo.head(ratio, model.observe_)
        with warnings.catch_warnings():  # a training demo far from a fold's others is measured as is
            warnings.simplefilter("ignore", ObservationWarning)
            pred = model.predict(obs)
        assert isinstance(pred, Prediction)
        hand = pred.human_mean.get(group)
        t_obs = float(obs.t[-1])
        anchors, anchor_s = rec.body.until(t_obs).last_seen(frames)
        later = np.flatnonzero(rec.body.t_s > t_obs)[::2]
        if not pred.known or hand is None or not np.isfinite(anchor_s[0]) or later.size == 0:
            continue
        residual = trust_residuals(rec.body, frames, gains, pred.t, hand, anchors, anchor_s)
        if not np.isfinite(residual[0]):
            continue
        fc = forecast_body(unit, pred.t, hand, anchors, anchor_s)
        t = rec.body.t_s[later]
        pos = fc.positions(t)
        err = np.full((later.size, n_f), np.nan)  # NaN: not tracked
        err[:, fc.index] = np.linalg.norm(pos - rec.positions_m[later][:, fc.index], axis=2)
        look = np.full_like(err, np.nan)
        look[:, fc.index] = t[:, None] - fc.anchor_s[None, :]
        out.append((err, look, np.tile(residual, (later.size, 1))))
    return out
