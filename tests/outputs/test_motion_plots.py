"""The figures of the robot's motion and of the evaluation's accuracy: their numbers (computed apart
from the drawing) and what is drawn from them."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.container import ErrorbarContainer
from test_plots import assert_png, captured

from ipromp_pin.exceptions import DataError
from ipromp_pin.motion.trajectory import JointLimits, Trajectory
from ipromp_pin.outputs import plots, plots_motion
from ipromp_pin.outputs.plot_series import motion_series


def test_held_spans_are_visible_and_cover_each_run():
    t = np.arange(10) * 0.1
    # one held sample at the end (an object received at the hand-over): half a period wide, not 0
    assert plots.held_spans(t, t >= 0.9) == [pytest.approx((0.85, 0.9))]
    held = (t >= 0.2) & (t <= 0.4) | (t >= 0.7)
    spans = plots.held_spans(t, held)
    assert spans == [pytest.approx((0.15, 0.45)), pytest.approx((0.65, 0.9))]
    assert plots.held_spans(t, np.zeros(10, bool)) == []
    assert plots.held_spans(t, np.ones(10, bool)) == [pytest.approx((0.0, 0.9))]


def test_torque_plot_shades_the_held_span(tmp_path, monkeypatch):
    figures = captured(monkeypatch)
    t = 0.7 + np.arange(300) * 0.01
    held = t >= t[150]
    tau = np.ones((300, 2))
    plots.plot_torques(
        t, tau, np.array([5.0, 5.0]), tmp_path / "t.png", held=held, events=[(t[150], "hand-over")]
    )
    ax = figures[0].axes[0]
    (span,) = [p for p in ax.patches if p.get_label() == "object held"]
    start, end = span.get_x(), span.get_x() + span.get_width()
    assert start == pytest.approx(t[150] - 0.005) and end == pytest.approx(t[-1])
    assert any(line.get_label() == "hand-over" for line in ax.lines)


def _motion(n: int = 50) -> tuple[Trajectory, JointLimits]:
    t = 0.5 + np.arange(n) * 0.01
    q = np.stack([np.sin(t), np.cos(t)], axis=1)
    qd = np.stack([np.cos(t), -np.sin(t)], axis=1)
    qdd = -q
    traj = Trajectory(t, q, qd, qdd, ("a", "b"))
    limits = JointLimits(
        np.full(2, -2.0), np.full(2, 2.0), np.full(2, 2.0), np.full(2, 3.0), np.full(2, 4.0), ("a", "b")
    )
    return traj, limits


def test_motion_series_gives_the_checks_jerk_and_segments():
    traj, limits = _motion()
    later = Trajectory(traj.t_s + 1.0, traj.q, traj.qd, traj.qdd, traj.joint_names)
    s = motion_series([traj, later], limits)
    assert s.t_s.size == 100 and list(np.unique(s.segment)) == [0, 1]
    # speed_limits' jerk: consecutive accelerations' difference over the control period
    np.testing.assert_allclose(s.jerk[1:50], np.diff(traj.qdd, axis=0) / 0.01)
    assert s.jerk[0].tolist() == [0.0, 0.0]
    np.testing.assert_allclose(s.ratios()[0], np.abs(traj.qd).max() / 2.0)
    with pytest.raises(DataError, match="no motion samples"):
        motion_series([], limits)


def test_joint_motion_and_separation_plots_are_drawn_and_check_their_input(tmp_path):
    traj, lim = _motion()
    s = motion_series([traj], lim)
    values = (s.q, s.qd, s.qdd, s.jerk)
    bounds = (lim.lower_rad, lim.upper_rad, lim.velocity_rad_s, lim.acceleration_rad_s2, lim.jerk_rad_s3)
    path = plots_motion.plot_joint_motion(
        s.t_s,
        values,
        bounds,
        tmp_path / "m.png",
        events=[(0.6, "start")],
        ticks_s=np.array([0.55, 0.7]),
        dpi=40,
    )
    assert_png(path, (800, 400))
    with pytest.raises(DataError, match="values\\[1\\]"):
        plots_motion.plot_joint_motion(s.t_s, (s.q, s.qd[:3], s.qdd), bounds[:4], tmp_path / "x.png")
    with pytest.raises(DataError, match="limits\\[2\\]"):
        plots_motion.plot_joint_motion(
            s.t_s, values, (*bounds[:2], -bounds[2], *bounds[3:]), tmp_path / "x.png"
        )
    t = s.t_s
    d = 0.5 - 0.1 * (t - t[0])
    ratio = np.clip(np.sin(3 * t), 0.0, None)
    path = plots_motion.plot_separation(
        t,
        d,
        np.full(t.size, 0.7),
        ratio,
        tmp_path / "s.png",
        hand_m=d - 0.1,
        planning_limit_ratio=0.9,
        dpi=50,
    )
    assert_png(path, (550, 350))
    with pytest.raises(DataError, match="speed_ratio"):
        plots_motion.plot_separation(t, d, d, ratio[:3], tmp_path / "x.png")
    with pytest.raises(DataError, match="planning_limit_ratio"):
        plots_motion.plot_separation(t, d, d, ratio, tmp_path / "x.png", planning_limit_ratio=0.0)


def _records(n_splits: int | None) -> list[dict]:
    rows = []
    for obs in ("orientation", "orientation,emg"):
        for k, task in enumerate(("rod", "tape")):
            acc = 0.6 + 0.1 * k + (0.2 if "emg" in obs else 0.0)
            std = None if n_splits is None else 0.05 * (k + 1)
            rows.append({"n_train": 10, "obs_ratio": 0.2, "observe": obs, "task": task, "accuracy": acc,
                         "accuracy_std": std, "n_splits": n_splits})  # fmt: skip
    return rows


def test_accuracy_bars_have_the_spread_over_splits_and_the_legend_beside(tmp_path, monkeypatch):
    bars = plots.accuracy_bars(_records(5))
    assert bars.settings == ["orientation", "orientation,emg"] and bars.n_splits == 5
    np.testing.assert_allclose(bars.mean[:, 0], [0.65, 0.85])
    np.testing.assert_allclose(bars.spread[:, 0], [0.075, 0.075])  # mean over the tasks of the stds
    figures = captured(monkeypatch)
    plots.plot_accuracy(_records(5), tmp_path / "a.png")
    ax = figures[0].axes[0]
    containers = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(containers) == 2
    for container, spread in zip(containers, bars.spread, strict=True):
        (segments,) = container.lines[2]
        heights = [seg[1, 1] - seg[0, 1] for seg in segments.get_segments()]
        np.testing.assert_allclose(heights, 2 * spread)
    assert "the std\nover 5 random splits" in ax.get_ylabel()
    legend = ax.get_legend()
    assert legend.get_bbox_to_anchor().x0 > ax.get_window_extent().x1  # beside the axes, over no bar
    # the paper's protocol has no splits: no error bars, and the label says none
    plots.plot_accuracy(_records(None), tmp_path / "b.png")
    ax = figures[1].axes[0]
    assert not [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert "split" not in ax.get_ylabel()
    # an accuracy of 1 has no error above it (the bar stays within [0, 1])
    perfect = [{**r, "accuracy": 1.0} for r in _records(5)]
    plots.plot_accuracy(perfect, tmp_path / "c.png")
    container = next(c for c in figures[2].axes[0].containers if isinstance(c, ErrorbarContainer))
    (segments,) = container.lines[2]
    ((low, high),) = [seg[:, 1] for seg in segments.get_segments()]
    assert high == pytest.approx(1.0) and low == pytest.approx(1.0 - 0.075)
    with pytest.raises(DataError, match="accuracy_std"):
        plots.accuracy_bars([{**_records(5)[0], "accuracy_std": -0.1}])
