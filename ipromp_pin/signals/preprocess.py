"""Signal preprocessing shared by the readers: clocks, alignment, resampling, EMG, quaternions.

Recorded streams arrive at different rates, stamped by different clocks. The
readers turn each one into a :class:`Stream` (sample times in [s] on one common
clock, values (N, D)) and :func:`align_streams` maps them onto one uniform grid
spanning the time all streams overlap.

Clock offsets (:func:`estimate_clock_offset`): every recorded message carries
its header stamp (set by the sender's clock) and the recording PC's receive
time. ``header - receive = offset - latency`` with latency >= 0, so the clock
offset is the upper envelope of ``header - receive``; a high quantile (default
0.9) of it is used, robust to a few late-stamped messages. Subtracting it maps
header stamps onto the recording PC's clock.

EMG (:func:`emg_envelope`, :class:`EnvelopeFilter`): rectified, then low-pass
filtered by a causal Butterworth filter started in its steady state for the
first sample. Every output depends only on the inputs up to it, so processing
the first n samples gives exactly the first n outputs of processing all of them
(what an online observer sees equals the truncated offline demo). The filter is
designed and applied here (:func:`butter_lowpass`, :func:`filter_steady_state`,
the filtering as one banded triangular solve), equal to ``scipy.signal``'s
``butter``, ``lfilter_zi`` and ``lfilter`` to rounding (the tests compare them):
importing ``scipy.signal`` (and with it ``scipy.stats``) took 0.2 s of every run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from ..exceptions import DataError

DEFAULT_EMG_CUTOFF_HZ = 4.0
"""Default low-pass cut-off of the EMG envelope, in [Hz]."""

DEFAULT_OFFSET_QUANTILE = 0.9
"""Quantile of ``header - receive`` taken as a stream's clock offset."""


# --------------------------------------------------------------------------------------------- EMG
def _envelope_coefficients(dt_s: float, cutoff_hz: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise DataError(None, "dt_s", f"sampling period must be positive, got {dt_s}")
    nyquist = 0.5 / dt_s
    if not (0.0 < cutoff_hz < nyquist):
        raise DataError(
            None, "emg_cutoff_hz", f"cut-off {cutoff_hz} Hz must be in (0, {nyquist:g}) Hz (Nyquist)"
        )
    return butter_lowpass(order, cutoff_hz / nyquist)


def butter_lowpass(order: int, wn: float) -> tuple[np.ndarray, np.ndarray]:
    """Digital Butterworth low-pass of ``order`` with the cut-off ``wn`` in (0, 1) (1: Nyquist), as
    transfer-function coefficients ``(b, a)`` (``a[0] = 1``), as ``scipy.signal.butter(order, wn)``:
    the analog prototype's poles, the cut-off pre-warped, the bilinear transform (sampling rate 2)."""
    m = np.arange(-order + 1, order, 2)
    poles = -np.exp(1j * np.pi * m / (2 * order)) * (4.0 * np.tan(np.pi * wn / 2.0))
    gain = (4.0 * np.tan(np.pi * wn / 2.0)) ** order * np.real(1.0 / np.prod(4.0 - poles))
    b = gain * np.poly(-np.ones(order))
    a = np.real(np.poly((4.0 + poles) / (4.0 - poles)))
    return b, a


def filter_steady_state(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Initial state (N,) of the transposed direct-form II filter ``(b, a)`` (``a[0] = 1``, order N)
    at rest under a unit step input (as ``scipy.signal.lfilter_zi``): scaled by the first sample, the
    filter starts in its steady state."""
    n = len(a) - 1
    companion = np.zeros((n, n))
    companion[0] = -a[1:]
    companion[1:, :-1] += np.eye(n - 1)
    return np.linalg.solve(np.eye(n) - companion.T, b[1:] - a[1:] * b[0])


def _iir_filter(b: np.ndarray, a: np.ndarray, x: np.ndarray, state: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter(b, a, x, axis=0, zi=state)[0]`` for ``a[0] = 1``: the recursion
    ``sum_k a_k y[n-k] = sum_k b_k x[n-k]`` (the initial state entering the first N rows) as one
    banded lower-triangular solve (LAPACK ``tbtrs``), every column of ``x`` (T, ...) at once."""
    n_samples, order = x.shape[0], len(a) - 1
    rhs = b[0] * x
    for k in range(1, min(order, n_samples - 1) + 1):
        rhs[k:] += b[k] * x[:-k]
    first = min(order, n_samples)
    rhs[:first] += state[:first]
    banded = np.empty((order + 1, n_samples))
    banded[:] = a[:, None]
    y, info = lapack.dtbtrs(banded, rhs.reshape(n_samples, -1), uplo="L")
    if info != 0:
        raise DataError(None, "emg", f"EMG filter failed (LAPACK tbtrs info {info})")
    return y.reshape(x.shape)


def emg_envelope(raw: np.ndarray, dt_s: float, cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ, order: int = 2):
    """Causal EMG envelope: rectify, then low-pass filter.

    Args:
        raw: EMG samples on a uniform grid, shape (T, C) (or (T,)).
        dt_s: Sampling period in [s].
        cutoff_hz: Low-pass cut-off in [Hz].
        order: Butterworth filter order.

    Returns:
        Envelope of the same shape as ``raw``; the filter starts in its steady
        state for the first (rectified) sample, so there is no start transient.
        ``emg_envelope(raw[:n])`` equals ``emg_envelope(raw)[:n]``.
    """
    x = np.abs(np.asarray(raw, dtype=float))
    if x.shape[0] == 0:
        return x.copy()
    if not np.all(np.isfinite(x)):
        raise DataError(None, "emg", "EMG contains NaN or inf")
    b, a = _envelope_coefficients(dt_s, cutoff_hz, order)
    zi = filter_steady_state(b, a)
    zi = zi.reshape((-1,) + (1,) * (x.ndim - 1)) * x[0]
    return _iir_filter(b, a, x, zi)


class EnvelopeFilter:
    """Streaming version of :func:`emg_envelope` (one sample at a time).

    Args:
        n_channels: Number of EMG channels C.
        dt_s: Sampling period in [s].
        cutoff_hz: Low-pass cut-off in [Hz].
        order: Butterworth filter order.
    """

    def __init__(
        self, n_channels: int, dt_s: float, cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ, order: int = 2
    ) -> None:
        self.n_channels = int(n_channels)
        self.b_, self.a_ = _envelope_coefficients(dt_s, cutoff_hz, order)
        self.state_: np.ndarray | None = None

    def update(self, sample: np.ndarray) -> np.ndarray:
        """Filter one sample (C,) and return the envelope value (C,)."""
        x = np.abs(np.asarray(sample, dtype=float)).reshape(self.n_channels)
        if not np.all(np.isfinite(x)):
            raise DataError(None, "emg", "EMG sample contains NaN or inf")
        b, a = self.b_, self.a_
        if self.state_ is None:
            self.state_ = filter_steady_state(b, a)[:, None] * x[None, :]
        z = self.state_  # transposed direct form II, one step
        y = b[0] * x + z[0]
        for k in range(len(z) - 1):
            z[k] = b[k + 1] * x + z[k + 1] - a[k + 1] * y
        z[-1] = b[-1] * x - a[-1] * y
        return y


# -------------------------------------------------------------------------------------- quaternions
def quaternion_continuity(q: np.ndarray) -> np.ndarray:
    """Unit-norm, sign-continuous quaternions.

    Each quaternion is normalised and its sign flipped where needed so that
    consecutive quaternions have a non-negative dot product (q and -q are the
    same rotation). Component order is kept (works for wxyz and xyzw).
    Rows with NaN stay NaN and are skipped when comparing signs.

    Args:
        q: Quaternions, shape (T, 4).

    Returns:
        Array (T, 4).
    """
    q = np.array(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4:
        raise DataError(None, "quaternion", f"expected shape (T, 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=1)
    valid = np.isfinite(norm)
    if np.any(valid & (norm < 1e-9)):
        raise DataError(None, "quaternion", "zero-norm quaternion")
    q[valid] /= norm[valid, None]
    idx = np.flatnonzero(valid)
    if idx.size > 1:
        v = q[idx]
        dots = np.einsum("ij,ij->i", v[1:], v[:-1])
        # Sign of each row relative to the first: cumulative product of the step signs.
        flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
        q[idx] = v * flips[:, None]
    return q


def normalize_quaternions(q: np.ndarray) -> np.ndarray:
    """Rows of ``q`` (T, 4) scaled to unit norm (NaN rows stay NaN)."""
    q = np.asarray(q, dtype=float)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return q / norm


# -------------------------------------------------------------------------------------- resampling
def resample(t_src: np.ndarray, values: np.ndarray, t_new: np.ndarray, kind: str = "linear") -> np.ndarray:
    """Resample values onto new times, NaN-aware.

    Args:
        t_src: Source times in [s], shape (N,), strictly increasing.
        values: Source values, shape (N,) or (N, D).
        t_new: Target times in [s], shape (M,).
        kind: ``"linear"`` interpolation (a target between two source samples is
            NaN if either is NaN), or ``"previous"`` (sample-and-hold: the last
            source sample at or before each target time, which is causal).

    Returns:
        Values at ``t_new``, shape (M,) or (M, D); NaN outside ``[t_src[0], t_src[-1]]``.
    """
    t_src = np.asarray(t_src, dtype=float)
    t_new = np.asarray(t_new, dtype=float)
    v = np.asarray(values, dtype=float)
    squeeze = v.ndim == 1
    if squeeze:
        v = v[:, None]
    if t_src.ndim != 1 or v.shape[0] != t_src.size:
        raise DataError(None, "t", f"{t_src.size} times do not match values of shape {v.shape}")
    if t_src.size < 2:
        raise DataError(None, "t", f"a stream needs at least 2 samples, got {t_src.size}")
    if np.any(np.diff(t_src) <= 0):
        raise DataError(None, "t", "source times are not strictly increasing")
    out = np.full((t_new.size, v.shape[1]), np.nan)
    inside = (t_new >= t_src[0]) & (t_new <= t_src[-1])
    tn = t_new[inside]
    if kind == "previous":
        i = np.searchsorted(t_src, tn, side="right") - 1
        out[inside] = v[i]
    elif kind == "linear":
        i = np.clip(np.searchsorted(t_src, tn, side="right") - 1, 0, t_src.size - 2)
        w = ((tn - t_src[i]) / (t_src[i + 1] - t_src[i]))[:, None]
        lo, hi = v[i], v[i + 1]
        # Exact hits on a source sample take that sample (a NaN neighbour does not spread).
        res = lo + w * (hi - lo)
        res = np.where(w == 0.0, lo, res)
        res = np.where(w == 1.0, hi, res)
        out[inside] = res
    else:
        raise DataError(None, "kind", f"unknown resampling kind {kind!r} (use 'linear' or 'previous')")
    return out[:, 0] if squeeze else out


# ---------------------------------------------------------------------------------------- clocks
def estimate_clock_offset(
    header_s: np.ndarray, receive_s: np.ndarray, quantile: float = DEFAULT_OFFSET_QUANTILE
) -> float:
    """Clock offset of a sender relative to the receiver, in [s].

    Args:
        header_s: Header stamps (sender clock) in [s], shape (N,).
        receive_s: Receive times (receiver clock) in [s], shape (N,).
        quantile: Quantile of ``header - receive`` used (the upper envelope,
            i.e. the messages with the least transport latency).

    Returns:
        ``offset`` such that ``header - offset`` is on the receiver's clock.
    """
    d = np.asarray(header_s, dtype=float) - np.asarray(receive_s, dtype=float)
    d = d[np.isfinite(d)]
    if d.size == 0:
        raise DataError(None, "time", "no time stamps to estimate a clock offset from")
    return float(np.quantile(d, quantile))


# ------------------------------------------------------------------------------------- alignment
@dataclass
class Stream:
    """One recorded stream on the common clock.

    Attributes:
        t: Sample times in [s] on the common clock, shape (N,).
        values: Samples, shape (N, D).
        channel_names: Names of the D channels.
        kind: Resampling kind: ``"linear"``, ``"previous"`` (sample-and-hold)
            ``"quaternion"`` (linear on sign-continuous quaternions, then
            renormalised) or ``"pose"`` (7 channels: a position, linear, then a quaternion).
        source: File the stream was read from (for error messages).
        clock_offset_s: Offset removed from its header stamps, in [s] (information).
        allow_missing: NaN values are known-missing samples (e.g. a skeleton tracker
            that lost the hand) rather than an error.
    """

    t: np.ndarray
    values: np.ndarray
    channel_names: tuple[str, ...]
    kind: str = "linear"
    source: str | None = None
    clock_offset_s: float = 0.0
    allow_missing: bool = False


def check_stream(name: str, stream: Stream) -> Stream:
    """Validate a stream and return it sorted in time with duplicate stamps dropped.

    Raises:
        DataError: empty or single-sample stream, NaN values, mismatched shapes.
    """
    t = np.asarray(stream.t, dtype=float)
    v = np.asarray(stream.values, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    if t.ndim != 1 or v.ndim != 2 or v.shape[0] != t.size:
        raise DataError(stream.source, name, f"{t.size} time stamps do not match values of shape {v.shape}")
    if v.shape[1] != len(stream.channel_names):
        raise DataError(stream.source, name, f"{v.shape[1]} channels but {len(stream.channel_names)} names")
    if t.size == 0:
        raise DataError(stream.source, name, "stream is empty")
    if not np.all(np.isfinite(t)):
        raise DataError(stream.source, name, "time stamps contain NaN or inf")
    bad = np.isinf(v) if stream.allow_missing else ~np.isfinite(v)
    if np.any(bad):
        rows, cols = np.nonzero(bad)
        raise DataError(
            stream.source,
            f"{name}/{stream.channel_names[cols[0]]}",
            f"{rows.size} NaN or inf values (first in message {rows[0]})",
        )
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t, v = t[keep], v[keep]
    if t.size < 2:
        raise DataError(
            stream.source, name, f"a stream needs at least 2 samples with distinct stamps, got {t.size}"
        )
    if stream.allow_missing and np.sum(np.all(np.isfinite(v), axis=1)) < 2:
        raise DataError(stream.source, name, "fewer than 2 valid (non-missing) samples")
    return Stream(
        t,
        v,
        tuple(stream.channel_names),
        stream.kind,
        stream.source,
        stream.clock_offset_s,
        stream.allow_missing,
    )


def align_streams(
    streams: Mapping[str, Stream], rate_hz: float, source: object | None = None
) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """Resample streams onto one uniform grid spanning their common time.

    Args:
        streams: Stream name -> :class:`Stream` (times on one common clock).
        rate_hz: Grid rate in [Hz].
        source: Demo source for error messages.

    Returns:
        ``(t, values, t0)``: grid times in [s] from 0, shape (T,); stream name ->
        resampled values (T, D); ``t0`` the grid start on the common clock in [s].

    Raises:
        DataError: a stream is empty or single-sample, or the streams do not
            overlap for at least two grid samples (naming the stream that ends
            before another starts).
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(source, "rate_hz", f"must be positive, got {rate_hz}")
    if not streams:
        raise DataError(source, None, "no streams to align")
    checked = {name: check_stream(name, s) for name, s in streams.items()}
    starts = {n: s.t[0] for n, s in checked.items()}
    ends = {n: s.t[-1] for n, s in checked.items()}
    first_end = min(ends, key=lambda n: ends[n])
    last_start = max(starts, key=lambda n: starts[n])
    t0, t1 = starts[last_start], ends[first_end]
    dt = 1.0 / rate_hz
    n = int(np.floor((t1 - t0) / dt + 1e-9)) + 1 if t1 >= t0 else 0
    if n < 2:
        src = checked[first_end].source or checked[last_start].source or source
        raise DataError(
            src,
            first_end,
            f"stream ends at {ends[first_end] - t0:+.3f} s relative to the start of stream "
            f"'{last_start}': the streams do not overlap (unsynchronised recording?)",
        )
    t = dt * np.arange(n)
    grid = np.minimum(t0 + t, t1)  # guard the last sample against round-off past the overlap
    out = {}
    for name, s in checked.items():
        if s.kind == "quaternion":
            v = resample(s.t, quaternion_continuity(s.values), grid, "linear")
            v = quaternion_continuity(normalize_quaternions(v))
        elif s.kind == "pose":  # x, y, z linear, then a quaternion (a gripper pose path)
            if s.values.shape[1] != 7:
                raise DataError(s.source, name, f"a pose stream has 7 channels, got {s.values.shape[1]}")
            q = resample(s.t, quaternion_continuity(s.values[:, 3:]), grid, "linear")
            v = np.hstack([resample(s.t, s.values[:, :3], grid, "linear"), quaternion_continuity(q)])
        else:
            v = resample(s.t, s.values, grid, s.kind)
        out[name] = v
    return t, out, float(t0)
