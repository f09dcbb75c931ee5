"""Streaming recognition: the estimate refreshed as the human's samples arrive one by one.

Each :meth:`StreamingEstimator.update` adds the new sample's contribution to running sufficient
statistics (``B^T B``, ``B^T y`` and ``y^T y`` for every phase candidate; one basis row per candidate
instead of the whole basis matrix). Channel groups with identical presence histories form one
observation part (one part while no sample missed a group). While the number of active basis
functions stays the same, the likelihood terms are updated incrementally
(:class:`~ipromp_pin.promp.likelihood.IncrementalTerms`: per part that received the sample a
Sherman-Morrison update of its ``X^-1`` and a rank-D update of ``P``, then one Cholesky factorisation
of ``Q`` per (task, candidate)); otherwise they are rebuilt from the statistics. The result equals
the one-shot recognition and prediction of a :class:`~ipromp_pin.data.Demo` holding the same
samples (to rounding).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from types import TracebackType

import numpy as np

from ..data import Demo
from ..exceptions import ObservationError
from .compiled import kernels
from .likelihood import IncrementalTerms, PartStats
from .observation import ObservationPart
from .posterior import IMPOSSIBLE_REASON, Prediction, Recognition
from .predictor import Predictor
from .stream_parts import PresencePatterns
from .window import RunningWindow, WindowSummary

_NOT_A_TIME = (bool, np.bool_, str, bytes)
"""Types refused as a sample time although ``float`` accepts them."""

_MAPPINGS = (dict, Mapping)
"""Accepted sample types (a dict first: faster to check than the abstract class)."""

MAX_GAP_FRACTION = 0.25
"""Largest time between two consecutive samples of one stream, as a fraction of the model's nominal
duration (about 0.75 s for the 3 s hand-overs): a sample that comes later is refused (a stamp from
another clock or a sample seconds late), and the stream goes on from the previous one. Missing
groups are sent as None at their own time, so a lost tracker does not make a gap."""

STREAM_EXTRA_BASIS = 4
"""Basis functions a stream keeps beyond the observed window's support, so that its incremental terms
are rebuilt only when the window reaches past them."""


class StreamingEstimator:
    """Refreshes the estimate as human samples arrive one by one.

    Channel groups that are missing in some samples are tracked separately: groups with identical
    presence histories share their statistics, as in the one-shot call.

    Used as a context manager (``with model.stream() as s: ...``), the estimator limits the BLAS
    threads once for the whole block instead of on every update.

    Args:
        predictor: The fitted model's :class:`~ipromp_pin.promp.predictor.Predictor`.
        limit_threads: Returns a context that limits the BLAS threads during an update.

    Attributes:
        incremental: The incremental likelihood terms (one part per presence history).
    """

    def __init__(
        self,
        predictor: Predictor,
        limit_threads: Callable[[], contextlib.AbstractContextManager] = contextlib.nullcontext,
    ) -> None:
        self.predictor = predictor
        self._limit_threads = limit_threads
        fm = predictor.fitted
        layout = fm.layout
        self._engine = engine = predictor.engine
        self._n = 0  # samples received: rows 0 .. n - 1 of the buffers below
        self._rows: list[np.ndarray] = []  # raw samples (D_o,), NaN in missing groups
        # the samples' times [s] and scaled values (0 in missing groups) as they arrived, in buffers
        # that double when full: what parts() hands the conditioning (views, no copy)
        self._t_buf = np.empty(64)
        self._y_buf = np.empty((64, layout.n_obs_dims))
        self._absent: list[int] = []  # per sample, bit i set when observed group i is missing
        self._gaps = False  # whether some sample missed a group
        self._last: Recognition | None = None
        self._n_obs = n_obs = layout.n_obs_dims
        self._inv_dur = 1.0 / (engine.alpha_unique * fm.duration_nominal_s)
        self._inv_dur_max = float(self._inv_dur.max())
        self._slices = [(g, *layout.slices[g]) for g in layout.observe]
        self._groups = set(layout.observe)
        self._kern = kernels()
        self._sums = PresencePatterns(layout, fm.basis, engine.alpha_unique.size, self._kern)
        self._window = RunningWindow(n_obs)  # the observed window's summary for the recognition head
        self._dim_group = np.concatenate([np.full(hi - lo, i) for i, (_, lo, hi) in enumerate(self._slices)])
        self.incremental: IncrementalTerms | None = IncrementalTerms(engine)
        self._longest = fm.longest_s
        self._beyond = -math.inf  # time of the latest sample no task explains (none: -inf)
        self._max_gap = MAX_GAP_FRACTION * fm.duration_nominal_s
        self._held: contextlib.AbstractContextManager | None = None
        self._support_until = -np.inf  # phases below this need at most incremental.ke basis functions
        b, enc = fm.basis, predictor.encoder
        self._encoder = enc
        self._sample_basis = (self._inv_dur, b.centres, b.width, b.step_factor)  # kernels.stream_sample
        self._sample_scaling = (enc.log_idx, enc.log_shift, enc.offset, enc.scale)
        # raw values that scale to the training mean: placeholders of missing groups in the one-call
        # scaling and check of a sample (None: they would not scale to plausible values)
        fill = fm.scaler.inverse(np.zeros(n_obs), enc.dims)
        self._fill: np.ndarray | None = fill if enc.scale_samples(fill.reshape(1, -1))[1] else None

    def __enter__(self) -> StreamingEstimator:
        self._held = self._limit_threads()
        self._held.__enter__()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        held, self._held = self._held, None
        if held is not None:
            held.__exit__(exc_type, exc, tb)

    @property
    def n_samples(self) -> int:
        """Number of samples received."""
        return self._n

    def update(self, t_s: float, sample: Mapping[str, np.ndarray | None]) -> Recognition | None:
        """Add one sample and return the refreshed recognition (None until 2 samples arrived).

        Args:
            t_s: Sample time in [s] from motion start (strictly increasing).
            sample: Observed group -> values (D,) in original units; a group that is absent or
                None is missing for this sample (e.g. a lost skeleton frame).
        """
        if isinstance(t_s, _NOT_A_TIME):  # float(True) is 1.0, float("1") is 1.0
            raise ObservationError("stream", "t", f"sample time {t_s!r} is not a number")
        try:
            t_s = float(t_s)
        except (TypeError, ValueError):
            raise ObservationError("stream", "t", f"sample time {t_s!r} is not a number") from None
        if not isinstance(sample, _MAPPINGS):
            raise ObservationError(
                "stream", "sample", f"expected a mapping group -> values, got {type(sample).__name__}"
            )
        t_prev = max(self._t_buf[self._n - 1] if self._n else -math.inf, self._beyond)
        if not math.isfinite(t_s) or t_s <= t_prev or t_s < -1e-9:
            raise ObservationError("stream", "t", f"sample time {t_s} is not after the previous sample")
        if self._n and t_s - t_prev > self._max_gap:
            raise ObservationError(
                "stream",
                "t",
                f"sample time {t_s:.3f} s is {t_s - t_prev:.2f} s after the previous sample "
                f"({t_prev:.3f} s): more than {self._max_gap:.2f} s ({MAX_GAP_FRACTION:g} of the "
                "model's nominal duration) cannot be one stream; the sample is refused",
            )
        if t_s > self._longest:  # no task explains it: unknown from now on (the sample is not used)
            self._beyond = t_s
            if self._last is not None:
                self._last = replace(
                    self._last, observed_until_s=t_s, known=False, novelty_score=math.inf,
                    novelty_p_value=0.0, unknown_reason=IMPOSSIBLE_REASON,
                )  # fmt: skip
            return self._last
        if not self._groups.issuperset(sample):
            g = next(g for g in sample if g not in self._groups)
            raise ObservationError(
                "stream", g, f"not an observed group ({list(self.predictor.fitted.layout.observe)})"
            )
        y = np.empty(self._n_obs)
        present = []
        absent = 0
        for i, (g, lo, hi) in enumerate(self._slices):
            v = sample.get(g)
            if v is None:
                y[lo:hi] = np.nan
                absent |= 1 << i
                continue
            try:
                raw = np.asarray(v)
                # numbers are copied into y as they are, anything else converted first (or refused)
                v = (raw if raw.dtype.kind in "fiu" else raw.astype(float)).reshape(-1)
            except (TypeError, ValueError):
                raise ObservationError("stream", g, f"sample values are not numbers: {v!r:.80}") from None
            if raw.dtype.kind == "b":
                raise ObservationError("stream", g, "sample values are booleans, not numbers")
            if v.size != hi - lo:
                raise ObservationError(
                    "stream", g, f"sample has {v.size} values, the model expects {hi - lo}"
                )
            y[lo:hi] = v
            present.append(g)
        self._encoder.align_sample(y)  # q and -q alike: the training data's sign (ObservationEncoder)
        if self._held is None:
            with self._limit_threads():
                return self._add(t_s, y, absent, present)
        return self._add(t_s, y, absent, present)

    def _check_finite(self, t_s: float, y: np.ndarray, present: list[str]) -> None:
        """Raise ObservationError naming the first present group of ``y`` with a NaN, an inf or an
        implausible value (:meth:`ObservationEncoder.check_values`); the stream is left as if the
        sample had never arrived."""
        encoder = self.predictor.encoder
        for g, lo, hi in self._slices:
            if g in present:
                encoder.check_values("stream", g, y[None, lo:hi], f"the sample at t={t_s:.3f} s")

    def _add(self, t_s: float, y: np.ndarray, absent: int, present: list[str]) -> Recognition | None:
        """Check and add the sample ``y`` (D,) (raw values, NaN in the groups flagged in ``absent``)
        to the statistics and refresh the recognition."""
        sums, window = self._sums, self._window
        if not absent and len(sums.patterns) == 1:
            # every group present and one presence history: finiteness check, scaling, basis row and
            # running sums in one call
            phi, ys, finite = self._kern.stream_sample(
                t_s, *self._sample_basis, y, *self._sample_scaling, sums.patterns[0][1], sums.proj,
                sums.sq, window.values, window.total, window.count,
            )  # fmt: skip
            if not finite:  # the statistics are unchanged
                self._check_finite(t_s, y, present)  # raises, naming the group
                raise ObservationError(
                    "stream", "sample", f"implausible value in the sample at t={t_s:.3f} s"
                )
            sums.received_by_all(t_s)
        else:
            ys = self._scaled(t_s, y, absent, present)
            phi = sums.accumulate(t_s * self._inv_dur, t_s, set(present), ys, self.incremental)
            window.add(ys, ((absent >> self._dim_group) & 1) == 0)
        n = self._n
        if n == self._t_buf.size:
            self._t_buf = np.concatenate([self._t_buf, np.empty(n)])
            self._y_buf = np.concatenate([self._y_buf, np.empty(self._y_buf.shape)])
        self._t_buf[n] = t_s
        self._y_buf[n] = ys
        self._n = n + 1
        self._rows.append(y)
        self._absent.append(absent)
        self._gaps = self._gaps or bool(absent)
        if self._n < 2:
            return None
        self._last = self._recognise(phi, ys)
        return self._last

    def _scaled(self, t_s: float, y: np.ndarray, absent: int, present: list[str]) -> np.ndarray:
        """The scaled values (D,) of the raw sample ``y`` (0 in the groups flagged in ``absent``),
        checked (ObservationError naming the group otherwise, the stream unchanged)."""
        missing = None
        if absent:
            missing = ((absent >> self._dim_group) & 1) == 1
            if self._fill is None:  # the per-group path
                self._check_finite(t_s, y, present)
                ys = np.zeros(self._n_obs)
                for g, lo, hi in self._slices:
                    if g in present:
                        ys[lo:hi] = self._encoder.scale_group(g, y[lo:hi])
                return ys
            y = np.where(missing, self._fill, y)  # placeholders that scale to plausible values
        out, finite = self._encoder.scale_samples(y.reshape(1, -1))
        if not finite:
            self._check_finite(t_s, y, present)  # raises, naming the group
            raise ObservationError("stream", "sample", f"implausible value in the sample at t={t_s:.3f} s")
        ys = out.reshape(-1)
        if missing is not None:
            ys[missing] = 0.0
        return ys

    def window(self) -> WindowSummary:
        """Summary of the samples received so far (scaled units), as the recognition head reads it."""
        return self._window.summary()

    def _stats(self) -> list[PartStats]:
        """Part statistics of the presence patterns with samples (each with its own active basis
        functions)."""
        stats = self._sums.stats(self._inv_dur_max)
        if sum(s.n for s in stats) < 2:
            raise ObservationError("stream", "t", "need at least 2 observed samples")
        return stats

    def _recognise(self, phi: np.ndarray, y: np.ndarray) -> Recognition:
        t_last = float(self._t_buf[self._n - 1])
        inc = self.incremental
        if inc is None:
            loglik = self._engine.log_likelihood(self._stats(), t_last)
        else:
            basis = self.predictor.fitted.basis
            z_last = t_last * self._inv_dur_max
            need = inc.ke if 0 <= inc.ke and z_last < self._support_until else basis.support_count(z_last)
            if inc.ke >= need:
                loglik = inc.add(phi, y, self._sums.proj, t_last, self._sums.receivers)
            else:
                # a few more basis functions than needed (each below the support threshold on the
                # observed window, as the one-shot truncation) so that resets stay rare; every
                # presence pattern's part with the same ones
                ke = min(basis.n_basis, need + STREAM_EXTRA_BASIS)
                sums = self._sums
                loglik = inc.reset([sums.pattern_stats(i, ke) for i in range(len(sums.patterns))], t_last)
                self._support_until = basis.support_limit(ke)
        fm = self.predictor.fitted
        window = self.window() if fm.head is not None or fm.novelty is not None else None
        return self.predictor.recognition_from_loglik(loglik, t_last, window)

    def observation(self) -> Demo:
        """The samples received so far as a :class:`Demo`."""
        layout = self.predictor.fitted.layout
        rows = np.array(self._rows).reshape(len(self._rows), self._n_obs)
        bits = np.array(self._absent, dtype=np.int64)
        gaps = (bits[:, None] >> np.arange(len(self._slices))[None, :]) & 1 == 1  # (n, groups)
        return Demo(
            task="",
            name="stream",
            source="stream",
            t=self._t_buf[: self._n].copy(),
            groups={g: rows[:, lo:hi].copy() for g, lo, hi in self._slices},
            channel_names={g: layout.channel_names[g] for g in layout.observe},
            missing={g: gaps[:, i] for i, g in enumerate(layout.observe) if gaps[:, i].any()},
        )

    def parts(self) -> tuple[list[ObservationPart], float]:
        """The samples received so far, scaled into observation parts (as
        :meth:`Predictor.encode <ipromp_pin.promp.predictor.Predictor.encode>` of :meth:`observation`
        gives them, to rounding: the values scaled on arrival, read-only views of the stream's
        buffers, no copy without missing samples; groups with identical presence share a part), and
        the time of the last one in [s]."""
        n = self._n
        if n < 2:
            raise ObservationError("stream", "t", f"need at least 2 samples, got {n}")
        t, y = self._t_buf[:n], self._y_buf[:n]
        t_last = float(t[-1])
        t.flags.writeable = False
        y.flags.writeable = False
        if not self._gaps:
            return [ObservationPart(t=t, dims=self._encoder.dims, y=y)], t_last
        bits = np.array(self._absent, dtype=np.int64)
        by_mask: dict[bytes, tuple[np.ndarray, list[int]]] = {}
        for i, (_, lo, hi) in enumerate(self._slices):
            valid = ((bits >> i) & 1) == 0
            if valid.any():
                by_mask.setdefault(valid.tobytes(), (valid, []))[1].extend(range(lo, hi))
        parts = []
        for valid, cols in by_mask.values():
            dims = np.array(cols, dtype=np.int64)
            parts.append(ObservationPart(t=t[valid], dims=self._encoder.dims[dims], y=y[np.ix_(valid, dims)]))
        return parts, t_last

    def recognition(self) -> Recognition:
        """Latest recognition (raises ObservationError before 2 samples)."""
        if self._last is None:
            raise ObservationError("stream", "t", f"need at least 2 samples, got {self._n}")
        return self._last

    def predict(
        self,
        condition_noise: float | None = None,
        conditioner: Predictor | None = None,
        estimates: bool = True,
    ) -> Prediction:
        """The latest recognition with the robot trajectory of its task conditioned on the samples so
        far at its MAP phase, with the noise ratio ``condition_noise`` (None: the model's own ``nu_c``;
        :meth:`Predictor.with_condition_noise`) or by ``conditioner``'s conditioner; then, with
        ``estimates``, on the model's hand-over estimates (:meth:`Predictor.with_estimates`, as
        :meth:`IProMP.predict` does). With the model's own noise ratio this equals :meth:`prediction`
        (to rounding) without recognising again.

        Raises:
            ObservationError: fewer than 2 samples received.
        """
        rec = self.recognition()
        parts, t_last = self.parts()
        predictor = conditioner or self.predictor.with_condition_noise(condition_noise)
        window = self.window() if estimates and predictor.fitted.handover is not None else None
        if self._held is None:
            with self._limit_threads():
                return self._predict(predictor, rec, parts, window, t_last, estimates)
        return self._predict(predictor, rec, parts, window, t_last, estimates)

    @staticmethod
    def _predict(
        predictor: Predictor,
        rec: Recognition,
        parts: list[ObservationPart],
        window: WindowSummary | None,
        t_last: float,
        estimates: bool,
    ) -> Prediction:
        pred = predictor.conditioner.condition(rec, parts)
        return predictor.with_estimates(pred, window, t_last) if estimates else pred

    def prediction(self) -> Prediction:
        """Conditioned prediction on all samples received so far (recognised again from the samples,
        as :meth:`IProMP.predict <ipromp_pin.promp.estimator.IProMP.predict>` of :meth:`observation`
        does, with the hand-over regression fused; from the stream's scaled samples, :meth:`parts`)."""
        with self._limit_threads():
            parts, t_last = self.parts()  # raises ObservationError before 2 samples
            return self.predictor.predict(parts, t_last)
