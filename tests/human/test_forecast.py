"""The predicted human (ipromp_pin.human.forecast, ipromp_pin.planning.human_forecast): the body
placed after the last observation where the model's cross-validated prediction is a tighter bound
than holding it, never where it is not trusted, and a plan through the predicted body refused."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.human import SKELETON_PREFIX, HumanMotion
from ipromp_pin.human.forecast import ForecastCalibration, forecast_body, quantile_radii
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.human_forecast import calibrate, forecast_of, predicted_human, with_forecast
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot
from ipromp_pin.robot.human_settings import HumanSettings
from ipromp_pin.safety import CheckContext, CheckSuite

HAND = "/left_hand_1"


def _calibration(frames: tuple[str, ...] = (HAND, "/head_1"), radius: float = 0.02) -> ForecastCalibration:
    """Hand gain 1, other frames 0.5; radii growing linearly to ``radius`` at 1 s."""
    n = len(frames)
    gains = np.stack([np.eye(3)] + [0.5 * np.eye(3)] * (n - 1))
    look = np.array([0.0, 0.5, 1.0])
    return ForecastCalibration(
        HAND, frames, gains, look, np.tile(look * radius, (n, 1)), np.full(n, 0.05), 0.95, 10, 40
    )


def _skeleton_dataset(n_tasks: int = 2, n_demos: int = 8) -> list[Demo]:
    """Synthetic demos with a tracked skeleton (the assumed pose, its hand following the demo's hand
    path) and the hand as an observed group ``/left_hand_1``."""
    ds = make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_demos, seed=3)
    settings = HumanSettings()
    out = []
    for d in ds.all_demos():
        hand = d.extras["hand_position"]
        body = HumanMotion.assumed_human(settings, d.t, hand)
        extras = dict(d.extras)
        for j, f in enumerate(body.frames):
            extras[SKELETON_PREFIX + f] = body.positions_m[:, j].copy()
        groups = {"emg": d.groups["emg"], HAND: hand.copy(), "robot": d.groups["robot"]}
        names = {g: d.channel_names[g] for g in ("emg", "robot")} | {HAND: ("x", "y", "z")}
        out.append(replace(d, groups=groups, channel_names=names, extras=extras, missing={}))
    return out


def test_calibration_round_trips_and_malformed_records_are_refused():
    cal = _calibration()
    back = ForecastCalibration.from_json(cal.to_json())
    assert back.frames == cal.frames and back.group == HAND
    np.testing.assert_array_equal(back.radius_m, cal.radius_m)
    bad = cal.to_json() | {"radius_m": [[0.0, 0.02, 0.01], [0.0, 0.01, 0.02]]}  # decreasing
    with pytest.raises(DataError, match="human_forecast"):
        ForecastCalibration.from_json(bad, "m.npz")
    with pytest.raises(DataError, match="hand frame"):
        ForecastCalibration.from_json(cal.to_json() | {"frames": ["/head_1", HAND]}, "m.npz")


def test_radii_are_quantiles_per_lookahead_made_non_decreasing():
    grid = np.array([0.0, 0.1, 0.2])
    look = np.array([0.05] * 40 + [0.15] * 40)
    err = np.concatenate([np.linspace(0, 0.1, 40), np.linspace(0, 0.05, 40)])  # second bin smaller
    r = quantile_radii(err, look, grid, 0.95, 30)
    assert r[0] == 0.0 and r[1] == pytest.approx(np.quantile(err[:40], 0.95))
    assert r[2] == r[1]  # non-decreasing
    assert np.isnan(quantile_radii(err[:50], look[:50], grid, 0.95, 30)[2])  # 10 errors: no evidence


def test_forecast_anchors_each_frame_and_moves_it_with_the_predicted_hand():
    cal = _calibration()
    t = np.linspace(0.0, 2.0, 21)
    hand = np.stack([t, 0 * t, 0 * t], axis=1)  # 1 m/s along x
    anchors = np.array([[5.0, 0.0, 0.0], [7.0, 1.0, 0.0]])
    fc = forecast_body(cal, t, hand, anchors, np.array([1.0, 0.5]))
    pos, r = fc.at(np.array([1.0, 1.5, 3.0]), speed_m_s=1.0)
    np.testing.assert_allclose(pos[0, 0], [5.0, 0.0, 0.0])  # the hand at its anchor time
    np.testing.assert_allclose(pos[1, 0], [5.5, 0.0, 0.0])
    np.testing.assert_allclose(pos[1, 1], [7.5, 1.0, 0.0])  # head: half the hand's 1 m since 0.5 s
    assert r[0, 0] == 0.0 and r[1, 0] == pytest.approx(0.01)
    # after the prediction's end (2 s) held at its end, growing at the human speed from there
    np.testing.assert_allclose(pos[2, 0], [6.0, 0.0, 0.0])
    assert r[2, 0] == pytest.approx(0.02 + 1.0)
    longer = forecast_body(cal, 2 * t, 2 * hand, anchors, np.array([1.0, 0.5]))
    assert longer.at(np.array([2.5]), 1.0)[1][0, 0] == np.inf  # 1.5 s ahead: beyond the calibration
    unseen = forecast_body(cal, t, hand, np.array([[5.0, 0, 0], [np.nan] * 3]), np.array([1.0, np.nan]))
    assert unseen.frames == (HAND,)


def _still_body(t_end: float = 2.0) -> HumanMotion:
    t = np.arange(0.0, t_end, 0.02)
    extras = {}
    for f, off in {"/head_1": (0.0, 0.0, 1.6), "/neck_1": (0.0, 0.0, 1.45), "/torso_1": (0.0, 0.0, 1.2),
                   "/left_shoulder_1": (0.0, 0.2, 1.45), "/right_shoulder_1": (0.0, -0.2, 1.45),
                   "/left_elbow_1": (0.1, 0.3, 1.25), "/right_elbow_1": (0.0, -0.25, 1.2),
                   HAND: (0.3, 0.35, 1.2), "/right_hand_1": (0.0, -0.25, 0.95),
                   "/left_hip_1": (0.0, 0.1, 0.95), "/right_hip_1": (0.0, -0.1, 0.95),
                   "/left_knee_1": (0.0, 0.1, 0.5), "/right_knee_1": (0.0, -0.1, 0.5)}.items():  # fmt: skip
        extras[SKELETON_PREFIX + f] = np.tile(np.array(off) + [2.0, 0.0, -1.0], (t.size, 1))
    demo = Demo(
        "task", "d", "demo.csv", t, {"emg": np.zeros((t.size, 8))}, {"emg": tuple("abcdefgh")}, extras=extras
    )
    body = HumanMotion.from_demo(demo)
    assert body is not None
    return body


def test_the_forecast_replaces_the_held_frame_only_where_it_is_tighter():
    body = _still_body().until(1.0)
    cal = _calibration(radius=0.5)  # 0.25 m at 0.5 s ahead: the held growth (at most 0.15 m) is tighter
    t = np.linspace(0.0, 2.0, 21)
    hand = np.stack([t, 0 * t, 0 * t], axis=1)
    anchors, seen = body.last_seen(cal.frames)
    fc = forecast_body(cal, t, hand, anchors, seen)
    moved = body.with_forecast(fc)
    head = body.frames.index("/head_1")
    p0, g0 = body.frames_at(np.array([0.5, 1.02, 1.5]))
    p1, g1 = moved.frames_at(np.array([0.5, 1.02, 1.5]))
    np.testing.assert_array_equal(p0[0], p1[0])  # before the horizon: as observed
    assert g1[1, head] == pytest.approx(0.02 * 0.5) and g1[1, head] < g0[1, head]  # 20 ms ahead: forecast
    np.testing.assert_allclose(p1[1, head] - p0[1, head], [0.01, 0.0, 0.0])  # half the hand's 2 cm
    np.testing.assert_array_equal(p1[2], p0[2])  # 0.5 s ahead: the held bound is tighter
    assert body.until(1.0).forecast is None and moved.until(1.5).forecast is None  # tied to its horizon


def test_after_the_horizon_the_held_frames_give_the_numbers_of_the_per_sample_path():
    body = _still_body(3.0).until(1.0)
    t = np.linspace(0.0, 2.0, 21)
    hand = np.stack([t, 0 * t, 0 * t], axis=1)
    cal = _calibration(radius=0.05)
    moved = body.with_forecast(forecast_body(cal, t, hand, *body.last_seen(cal.frames)))
    late = np.linspace(1.0, 2.5, 40)
    for human in (body, moved):
        fast = human.capsules(late)  # every time at or after the horizon
        general = human.capsules(np.concatenate([[0.5], late]))  # one before it: per-sample indexing
        for x, y in zip(fast, general, strict=True):
            np.testing.assert_array_equal(x, y[1:])


def test_a_plan_through_the_predicted_body_is_refused_and_one_beside_it_passes():
    robot = load_robot("baxter_left")
    q = np.zeros(robot.n_joints)
    gripper = ee_positions(robot, q[None, :])[0]
    still = Trajectory(np.array([1.0, 1.5, 2.0, 2.5]), np.tile(q, (4, 1)), np.zeros((4, 7)), np.zeros((4, 7)),
                       tuple(robot.joint_names))  # fmt: skip
    suite = CheckSuite.build(robot, ["human_clearance"])
    body = _still_body(3.0).until(1.0)
    cal = _calibration(frames=(HAND, "/head_1"), radius=0.02)
    cal = replace(cal, gains=np.stack([np.eye(3), np.eye(3)]))  # the head moves as the hand does
    t = np.linspace(0.0, 3.0, 31)
    anchors, seen = body.last_seen(cal.frames)
    head = anchors[1]
    # the predicted hand moves the head onto the robot's gripper by 1.9 s
    path = np.clip((t - 1.0) / 0.9, 0.0, 1.0)[:, None] * (gripper - head)[None, :] + anchors[0]
    moved = body.with_forecast(forecast_body(cal, t, path, anchors, seen))
    held_verdict = suite.run(still, CheckContext(human=body))[0]
    moved_verdict = suite.run(still, CheckContext(human=moved))[0]
    assert held_verdict.passed and not moved_verdict.passed


def test_calibrated_on_demos_with_a_skeleton_used_when_trusted_and_stored_in_the_model(tmp_path):
    demos = _skeleton_dataset()
    model = IProMP(observe=["emg", HAND], head=False, handover=False, coupling="all").fit(demos)
    settings = HumanSettings()
    cal = calibrate(model, demos, settings)
    assert cal is not None and cal.frames[0] == HAND and cal.group == HAND
    assert np.all(np.diff(cal.radius_m, axis=1) >= 0)
    moving = [cal.frames.index(f) for f in (HAND, "/left_elbow_1")]  # the assumed body's others stand
    assert np.all(cal.radius_m[moving, 1] > 0) and np.all(cal.radius_m[:, 1] < 0.2)
    assert cal.n_demos == len(demos)
    assert calibrate(model, demos, replace(settings, handing_arm="held")) is None  # held: none made
    stored = with_forecast(model, demos, settings)
    stored.save(tmp_path / "m.npz")
    loaded = IProMP.load(tmp_path / "m.npz")
    back = forecast_of(loaded)
    assert back is not None and np.array_equal(back.radius_m, cal.radius_m)
    assert forecast_of(loaded, replace(settings, handing_arm="held")) is None
    demo = demos[1]
    obs = demo.head(0.4, loaded.observe_)
    pred = loaded.predict(obs)
    body = HumanMotion.from_demo(demo, settings)
    assert body is not None
    known = body.until(float(obs.t[-1]))
    out = predicted_human(known, pred, back)
    assert out is not None and out.forecast is not None
    assert predicted_human(known, replace(pred, known=False), back) is known  # an unknown task: held
    strict = replace(back, offset_m=np.zeros(len(back.frames)))  # nothing follows that closely: held
    assert predicted_human(known, pred, strict) is known
    assert predicted_human(known, pred, None) is known


def test_no_calibration_without_an_observed_hand_frame_or_a_skeleton():
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=1)
    demos = ds.all_demos()
    model = IProMP(observe=["emg"], head=False, handover=False, coupling="all").fit(demos)
    assert calibrate(model, demos) is None
