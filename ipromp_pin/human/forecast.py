"""The body as the model predicts it: where the planner's body leaves the held frames.

After the planner's last observation every tracked frame is *held* where it was last seen and grows
at the human speed ``v`` (:class:`~ipromp_pin.human.body.HumanMotion`): a bound in every direction.
When the model observes a hand frame (:data:`HAND_FRAMES`, e.g. ``/left_hand_1``), its prediction
says where that hand goes next, and the body moves with it (the arm most, the head and trunk a
little). A :class:`ForecastCalibration` (fitted on the training demos by cross-validation,
:mod:`ipromp_pin.planning.human_forecast`) says how far that is to be trusted:

* each tracked frame of the body is **anchored** where it was last seen, at time ``t_f``, and moved
  by a gain ``G_f`` (3, 3) times the predicted hand's displacement since ``t_f``:
  ``x_f(t) = x_f(t_f) + G_f (mu(t) - mu(t_f))`` (``G`` the identity for the hand itself; least
  squares over the training demos' recorded displacements for the others);
* its uncertainty radius is the cross-validated quantile ``r_f(t - t_f)`` of that forecast's error
  on held-out training demos, at the look-ahead ``t - t_f`` (non-decreasing in it);
* at each time the frame takes the forecast only where ``r_f`` is below the held growth
  ``min(v (t - t_f), max_inflation)``: both are bounds of where the frame is, and the smaller
  sphere is the tighter one. Beyond the prediction's end (the predicted hand-over) the forecast
  holds its last position and grows at ``v``.

The forecast exists only for a known task whose predicted hand moved as the observed one did over
the last 0.2 s before it was seen (within the calibration's ``offset_m``); a frame that moved unlike
its forecast over that window (beyond its own ``offset_m``) stays held, and so does the whole body
when the hand does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import DataError

HAND_FRAMES = ("/left_hand_1", "/right_hand_1")
"""The body model's hand frames: an observed group that tracks one drives the forecast."""

FORECAST_VERSION = 1
"""Version of :meth:`ForecastCalibration.to_json`'s record."""

MAX_LOOKAHEAD_POINTS = 1000
"""Largest number of look-ahead points a stored calibration may have."""


@dataclass(frozen=True)
class ForecastCalibration:
    """How the body moves with the predicted hand, and how far that is trusted (module docstring).

    Attributes:
        group: The model's observed group that tracks the hand (its name in the recordings).
        frames: The body frames (F,) it places, the hand (one of :data:`HAND_FRAMES`) first.
        gains: Displacement gains (F, 3, 3): a frame moves ``G_f`` times the hand's displacement.
        lookahead_s: Look-ahead times (L,) [s], from 0, increasing.
        radius_m: Forecast error radius (F, L) [m] at each look-ahead (the cross-validated quantile),
            non-decreasing along L.
        offset_m: Per frame (F,) [m]: the largest difference between its observed displacement over
            the trust window before it was last seen and the displacement the prediction gives it
            for which the forecast places it (the same quantile of that difference); the hand's
            gates the whole forecast.
        quantile: The error quantile of ``radius_m`` and ``offset_m``.
        n_demos: Training demos the errors were measured on (held out in turn).
        n_forecasts: Forecasts measured (demos x observed fractions, known tasks only).
    """

    group: str
    frames: tuple[str, ...]
    gains: np.ndarray
    lookahead_s: np.ndarray
    radius_m: np.ndarray
    offset_m: np.ndarray
    quantile: float
    n_demos: int
    n_forecasts: int

    def to_json(self) -> dict[str, Any]:
        """JSON-serialisable form (the model file's header ``human_forecast``)."""
        return {
            "version": FORECAST_VERSION,
            "group": self.group,
            "frames": list(self.frames),
            "gains": self.gains.tolist(),
            "lookahead_s": self.lookahead_s.tolist(),
            "radius_m": self.radius_m.tolist(),
            "offset_m": self.offset_m.tolist(),
            "quantile": float(self.quantile),
            "n_demos": int(self.n_demos),
            "n_forecasts": int(self.n_forecasts),
        }

    @classmethod
    def from_json(cls, d: Mapping[str, Any], source: str = "model file") -> ForecastCalibration:
        """The calibration of :meth:`to_json`.

        Raises:
            DataError: a malformed record (naming ``source`` and the field ``human_forecast``).
        """
        try:
            if d.get("version") != FORECAST_VERSION:
                raise ValueError(f"version {d.get('version')!r} is not {FORECAST_VERSION}")
            frames = tuple(str(f) for f in d["frames"])
            gains = np.asarray(d["gains"], dtype=float)
            look = np.asarray(d["lookahead_s"], dtype=float)
            radius = np.asarray(d["radius_m"], dtype=float)
            cal = cls(
                str(d["group"]), frames, gains, look, radius, np.asarray(d["offset_m"], dtype=float),
                float(d["quantile"]), int(d["n_demos"]), int(d["n_forecasts"]),
            )  # fmt: skip
            cal.validate()
            return cal
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(source, "human_forecast", f"malformed human forecast ({exc})") from None

    def validate(self) -> None:
        """Raise ValueError when the arrays are inconsistent or not finite."""
        n_f, n_l = len(self.frames), self.lookahead_s.size
        if n_f == 0 or self.frames[0] not in HAND_FRAMES or len(set(self.frames)) != n_f:
            raise ValueError(f"frames {list(self.frames)} do not start with a hand frame or repeat")
        if (
            self.gains.shape != (n_f, 3, 3)
            or self.radius_m.shape != (n_f, n_l)
            or self.offset_m.shape != (n_f,)
        ):
            raise ValueError(f"shapes {self.gains.shape}, {self.radius_m.shape} do not fit {n_f} frames")
        if not 2 <= n_l <= MAX_LOOKAHEAD_POINTS or self.lookahead_s[0] != 0.0:
            raise ValueError(f"{n_l} look-aheads (2 to {MAX_LOOKAHEAD_POINTS}, from 0 s)")
        if np.any(np.diff(self.lookahead_s) <= 0) or np.any(np.diff(self.radius_m, axis=1) < 0):
            raise ValueError("look-aheads not increasing or radii decreasing")
        finite = [self.gains, self.lookahead_s, self.radius_m, self.offset_m, np.array([self.quantile])]
        if not all(np.all(np.isfinite(a)) for a in finite) or np.any(self.radius_m < 0):
            raise ValueError("non-finite or negative values")
        if not (0.5 <= self.quantile < 1.0) or np.any(self.offset_m < 0):
            raise ValueError(f"quantile {self.quantile} outside [0.5, 1) or negative offset")


@dataclass(frozen=True)
class BodyForecast:
    """Frames of the body placed by the prediction after the planner's last observation.

    Attributes:
        frames: Body frame names (Fp,): the calibration's frames that were seen.
        index: Each one's index (Fp,) among the calibration's frames.
        anchor_s: When each frame was last seen (Fp,) [s] (its look-ahead starts there).
        t_s: Times (K,) [s] of the predicted hand path, increasing.
        positions_m: Forecast positions (K, Fp, 3) [m].
        calibration: The calibration giving the radii.
    """

    frames: tuple[str, ...]
    index: np.ndarray
    anchor_s: np.ndarray
    t_s: np.ndarray
    positions_m: np.ndarray
    calibration: ForecastCalibration

    def positions(self, t_s: np.ndarray) -> np.ndarray:
        """Positions (N, Fp, 3) [m] at times (N,) [s]: interpolated on the predicted path, held at
        its ends outside it."""
        t = np.clip(np.atleast_1d(np.asarray(t_s, dtype=float)), self.t_s[0], self.t_s[-1])
        k = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, self.t_s.size - 2)
        span = self.t_s[k + 1] - self.t_s[k]
        w = np.where(span > 0, (t - self.t_s[k]) / np.where(span > 0, span, 1.0), 0.0)
        p = self.positions_m
        return p[k] + (p[k + 1] - p[k]) * w[:, None, None]

    def at(self, t_s: np.ndarray, speed_m_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, Fp, 3) [m] (:meth:`positions`) and radii (N, Fp) [m] at times (N,) [s]:
        after the path's end (the predicted hand-over) the radius grows at ``speed_m_s`` from
        there; ``inf`` before the anchor or beyond the calibration."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        pos = self.positions(t)
        tc = np.clip(t, self.t_s[0], self.t_s[-1])
        look = tc[:, None] - self.anchor_s[None, :]  # (N, Fp)
        grid, radii = self.calibration.lookahead_s, self.calibration.radius_m
        radius = np.stack([np.interp(look[:, j], grid, radii[i]) for j, i in enumerate(self.index)], axis=1)
        radius[(look < 0.0) | (look > grid[-1])] = np.inf  # no evidence there
        radius += speed_m_s * np.maximum(t - self.t_s[-1], 0.0)[:, None]
        radius[t[:, None] < self.anchor_s[None, :]] = np.inf
        return pos, radius


def forecast_body(
    calibration: ForecastCalibration,
    t_pred_s: np.ndarray,
    hand_pred_m: np.ndarray,
    anchors_m: np.ndarray,
    anchor_s: np.ndarray,
) -> BodyForecast:
    """The body's forecast from a predicted hand path.

    Args:
        calibration: The model's forecast calibration.
        t_pred_s: Prediction times (M,) [s] on the human's clock, increasing.
        hand_pred_m: Predicted hand positions (M, 3) [m], in the frame of the anchors.
        anchors_m: Each calibration frame's last seen position (F, 3) [m] (NaN: not seen, left out).
        anchor_s: When it was seen (F,) [s].
    """
    t = np.asarray(t_pred_s, dtype=float)
    mu = np.asarray(hand_pred_m, dtype=float)
    seen = np.flatnonzero(np.all(np.isfinite(anchors_m), axis=1) & np.isfinite(anchor_s))
    at_s = np.asarray(anchor_s, dtype=float)[seen]
    mu_at = np.stack([np.interp(at_s, t, mu[:, c]) for c in range(3)], axis=1)  # (Fp, 3)
    disp = mu[:, None, :] - mu_at[None, :, :]  # (M, Fp, 3)
    moved = np.einsum("fij,mfj->mfi", calibration.gains[seen], disp)
    frames = tuple(calibration.frames[i] for i in seen)
    return BodyForecast(frames, seen, at_s, t, anchors_m[seen][None, :, :] + moved, calibration)


def fit_gains(hand_disp: np.ndarray, frame_disp: np.ndarray, ridge: float = 1e-6) -> np.ndarray:
    """The gain ``G`` (3, 3) minimising ``sum |frame_disp - G hand_disp|^2`` over displacement
    pairs (N, 3) [m] (ridge-regularised normal equations, solved by Cholesky)."""
    a = hand_disp.T @ hand_disp + ridge * np.eye(3)
    b = hand_disp.T @ frame_disp
    chol = np.linalg.cholesky(a)
    return np.linalg.solve(chol.T, np.linalg.solve(chol, b)).T


def quantile_radii(
    errors: np.ndarray, lookahead: np.ndarray, grid: np.ndarray, q: float, min_count: int
) -> np.ndarray:
    """The ``q`` quantile of the finite forecast errors (N,) [m] per look-ahead bin of ``grid`` (L,)
    [s], from 0: the error at look-ahead ``d`` (N,) [s] counts in the bin of the first grid point at
    or after it; 0 at look-ahead 0 (the forecast starts where the frame was seen); made non-decreasing;
    NaN from the first bin with fewer than ``min_count`` errors on."""
    idx = np.searchsorted(grid, lookahead, side="left")
    out = np.full(grid.size, math.nan)
    out[0] = 0.0
    for k in range(1, grid.size):
        e = errors[(idx == k) & np.isfinite(errors)]
        if e.size < min_count:
            break
        out[k] = float(np.quantile(e, q))
    ok = np.isfinite(out)
    out[ok] = np.maximum.accumulate(out[ok])
    return out
