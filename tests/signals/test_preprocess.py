"""Tests of ipromp_pin.signals.preprocess: EMG envelope, quaternions, resampling, clocks, alignment."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import DataError
from ipromp_pin.signals.preprocess import (
    EnvelopeFilter,
    Stream,
    align_streams,
    emg_envelope,
    estimate_clock_offset,
    quaternion_continuity,
    resample,
)


def test_emg_envelope_is_causal_and_matches_streaming():
    rng = np.random.default_rng(0)
    raw = rng.normal(0, 1, (120, 8)) * np.linspace(1, 5, 120)[:, None]
    full = emg_envelope(raw, 0.02, 4.0)
    for n in (2, 10, 37, 119):
        np.testing.assert_allclose(emg_envelope(raw[:n], 0.02, 4.0), full[:n], rtol=0, atol=1e-12)
    filt = EnvelopeFilter(8, 0.02, 4.0)
    online = np.array([filt.update(x) for x in raw])
    np.testing.assert_allclose(online, full, atol=1e-10)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_envelope_filter_equals_scipy_signal(order):
    """The filter is designed and applied without scipy.signal (0.2 s to import), equal to it."""
    from scipy import signal

    from ipromp_pin.signals.preprocess import butter_lowpass, filter_steady_state

    for wn in (0.05, 0.16, 0.5, 0.9):
        b, a = butter_lowpass(order, wn)
        b_ref, a_ref = signal.butter(order, wn)
        np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=0)
        np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(filter_steady_state(b, a), signal.lfilter_zi(b_ref, a_ref), rtol=1e-12)
    rng = np.random.default_rng(order)
    for n in (1, 2, order + 1, 300):
        raw = rng.normal(0, 50, (n, 8))
        b, a = signal.butter(order, 4.0 / 25.0)
        x = np.abs(raw)
        ref, _ = signal.lfilter(b, a, x, axis=0, zi=signal.lfilter_zi(b, a)[:, None] * x[0])
        np.testing.assert_allclose(emg_envelope(raw, 0.02, 4.0, order), ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(emg_envelope(raw[:, 0], 0.02, 4.0, order), ref[:, 0], rtol=1e-12)


def test_emg_envelope_rectifies_and_starts_in_steady_state():
    const = np.full((50, 2), -3.0)
    np.testing.assert_allclose(emg_envelope(const, 0.02, 4.0), 3.0, atol=1e-9)
    # A fast alternating signal is smoothed towards its rectified mean.
    alt = np.tile([[1.0], [-1.0]], (100, 1))
    env = emg_envelope(alt, 0.02, 2.0)
    assert np.all(env[-50:] > 0.9) and np.all(env[-50:] < 1.1)
    with pytest.raises(DataError, match="cut-off"):
        emg_envelope(const, 0.02, 30.0)


def test_quaternion_continuity_flips_signs_and_normalises():
    q = np.array([[1.0, 0, 0, 0], [-2.0, 0, 0, 0.1], [np.nan] * 4, [0.9, 0.0, 0.0, -0.1], [-1.0, 0, 0, 0]])
    out = quaternion_continuity(q)
    ok = np.isfinite(out[:, 0])
    np.testing.assert_allclose(np.linalg.norm(out[ok], axis=1), 1.0)
    assert np.all(out[ok, 0] > 0)
    assert np.isnan(out[2]).all()
    with pytest.raises(DataError, match="zero-norm"):
        quaternion_continuity(np.zeros((2, 4)))


def test_resample_linear_previous_and_nan():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    v = np.array([0.0, 10.0, np.nan, 30.0])
    new = np.array([-0.5, 0.0, 0.5, 1.0, 1.5, 3.0, 3.5])
    lin = resample(t, v, new)
    np.testing.assert_allclose(lin[[1, 2, 3, 5]], [0.0, 5.0, 10.0, 30.0])
    assert np.isnan(lin[0]) and np.isnan(lin[4]) and np.isnan(lin[6])
    prev = resample(t, v, new, "previous")
    np.testing.assert_allclose(prev[[1, 2, 3, 4, 5]], [0.0, 0.0, 10.0, 10.0, 30.0])
    with pytest.raises(DataError):
        resample(t, v, new, "cubic")
    with pytest.raises(DataError, match="at least 2"):
        resample(t[:1], v[:1], new)


def test_estimate_clock_offset_is_robust():
    rng = np.random.default_rng(1)
    receive = np.sort(rng.uniform(0, 4, 300))
    latency = rng.exponential(0.004, 300)
    header = receive - latency + 3.95  # sender clock 3.95 s ahead, stamps before sending
    header[::50] -= 0.5  # a few very late messages
    assert estimate_clock_offset(header, receive) == pytest.approx(3.95, abs=0.005)


def _stream(t0, n, rate=50.0, d=2, **kw):
    t = t0 + np.arange(n) / rate
    return Stream(t, np.column_stack([t] * d), tuple(f"c{i}" for i in range(d)), **kw)


def test_align_streams_spans_the_overlap_on_a_uniform_grid():
    a = _stream(10.0, 200, 100.0)  # 10.00 .. 11.99
    b = _stream(10.3, 60, 33.0, source="b.csv")  # 10.3 .. 12.09
    t, out, t0 = align_streams({"a": a, "b": b}, 50.0)
    assert t0 == pytest.approx(10.3)
    assert t[0] == 0.0 and np.allclose(np.diff(t), 0.02)
    assert t0 + t[-1] <= 11.99 + 1e-9 and t0 + t[-1] > 11.99 - 0.02
    np.testing.assert_allclose(out["a"][:, 0], t0 + t, atol=1e-9)
    np.testing.assert_allclose(out["b"][:, 1], t0 + t, atol=1e-9)


def test_align_streams_errors():
    a = _stream(0.0, 100)
    with pytest.raises(DataError, match="do not overlap") as e:
        align_streams({"a": a, "late": _stream(50.0, 100, source="late.csv")}, 50.0)
    assert "late.csv" in str(e.value) or "'a'" in str(e.value)
    with pytest.raises(DataError, match="at least 2"):
        align_streams({"a": a, "one": _stream(0.5, 1, source="one.csv")}, 50.0)
    with pytest.raises(DataError, match="empty"):
        align_streams({"a": a, "none": _stream(0.5, 0)}, 50.0)
    bad = _stream(0.0, 100, source="nan.csv")
    bad.values[5, 1] = np.nan
    with pytest.raises(DataError, match=r"nan\.csv: field 'x/c1'.*NaN"):
        align_streams({"a": a, "x": bad}, 50.0)
    # Known-missing samples are allowed when flagged so.
    ok = _stream(0.0, 100, allow_missing=True)
    ok.values[5] = np.nan
    _, out, _ = align_streams({"a": a, "x": ok}, 50.0)
    assert np.isnan(out["x"][5]).all() and np.isfinite(out["x"][7]).all()
