"""The observed window's summary (first, mean and last valid value per dim), written once in
``ipromp_pin.promp.window`` and read by the head, the hand-over regression, the stream and the
baselines."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.promp.observation import ObservationPart
from ipromp_pin.promp.window import RunningWindow, WindowSummary, window_features, window_summary


def test_window_summary_of_valid_rows_and_of_none():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(9, 3))
    valid = np.array([0, 1, 1, 0, 1, 0, 0, 1, 0], dtype=bool)
    s = window_summary(y, valid)
    assert np.array_equal(s, np.stack([y[1], y[valid].mean(axis=0), y[7]]))
    assert np.array_equal(window_summary(y), np.stack([y[0], y.mean(axis=0), y[-1]]))
    assert np.isnan(window_summary(y, np.zeros(9, dtype=bool), fill=np.nan)).all()
    assert not window_summary(y[:0]).any() and window_summary(y[:0]).shape == (3, 3)


def test_window_features_are_the_mean_then_last_rows():
    values = np.arange(12.0).reshape(3, 4)
    assert window_features(values).tolist() == [4, 5, 6, 7, 8, 9, 10, 11]
    assert window_features(values.reshape(-1), np.array([1, 3])).tolist() == [5, 7, 9, 11]


def test_window_summary_of_parts_with_gaps():
    rng = np.random.default_rng(0)
    t = np.arange(10) * 0.1
    a = ObservationPart(t=t[[0, 2, 5, 7]], dims=np.array([0, 3]), y=rng.normal(size=(4, 2)))
    b = ObservationPart(t=t, dims=np.array([2]), y=rng.normal(size=(10, 1)))
    w = WindowSummary.from_parts([a, b], 5)
    assert np.array_equal(w.values[:, [0, 3]], window_summary(a.y))
    assert w.first[2] == b.y[0, 0] and w.last[2] == b.y[-1, 0] and w.mean[2] == b.y.mean()
    assert not w.values[:, [1, 4]].any()  # never observed: the training mean
    assert np.array_equal(w.vector()[:5], w.first) and w.vector().shape == (15,)
    with pytest.raises(ValueError, match="share a dim"):
        WindowSummary.from_parts([a, ObservationPart(t=t[:2], dims=np.array([3]), y=np.ones((2, 1)))], 5)


def test_running_window_follows_the_summary_of_its_samples():
    rng = np.random.default_rng(1)
    y = rng.normal(size=(12, 4))
    have = rng.random((12, 4)) > 0.3
    have[:, 3] = False  # a dim that never arrives
    run = RunningWindow(4)
    for i in range(12):
        run.add(y[i], have[i])
    expected = np.stack([window_summary(y[:, [d]], have[:, d])[:, 0] for d in range(4)], axis=1)
    assert np.allclose(run.summary().values, expected, rtol=1e-14, atol=0)
    assert not run.values[:, 3].any()
