"""The body model's self-check and the registration's calibration (ipromp_pin.human.fit) on
synthetic demos with a tracked skeleton (the assumed human, its handing hand on the demo's hand path):
a body that fits gets no correction; a body moved into the demonstrated robot's path or away from
the gripper is flagged (which part, how deep, in how many demos), and the calibration moves it back
until it fits; the calibrated body keeps its radii and a plan through it is still refused; the
finding survives the model file; ``run``/``plan``/``replay`` warn or, with ``--strict-human``, refuse."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers_cli import one_error_line, run_tiny

from ipromp_pin import app as cli
from ipromp_pin.app.human_fit import HumanModelMisfit, check_human_fit
from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.human import BODY_PARTS, SKELETON_PREFIX, HumanMotion, fit
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot
from ipromp_pin.safety import CheckContext
from ipromp_pin.safety.human_clearance import HumanClearance

NAMES = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


@pytest.fixture(scope="module")
def demos():
    return make_synthetic_dataset(seed=0).all_demos()[:12]


def with_skeleton(robot, demo: Demo, shift_m=(0.0, 0.0, 0.0)) -> Demo:
    """``demo`` with a tracked skeleton as the reader writes it: the assumed human on the demo's
    hand path, every frame (the hand too: a registration moves all of them) moved by ``shift_m``."""
    h = HumanMotion.assumed_human(robot.settings.human, t_s=demo.t, hand_m=demo.extras["hand_position"])
    extras = dict(demo.extras)
    for j, f in enumerate(h.frames):
        extras[SKELETON_PREFIX + f] = h.positions_m[:, j] + np.asarray(shift_m)
    return dataclasses.replace(demo, extras=extras)


def session(robot, demos, shift_m=(0.0, 0.0, 0.0)):
    return fit.demo_evidence([with_skeleton(robot, d, shift_m) for d in demos], robot)


def test_a_body_that_fits_is_not_corrected(robot, demos):
    found = fit.self_check([with_skeleton(robot, d) for d in demos], robot)
    assert found is not None and found.fits and found.recorded.fits
    assert found.recorded.n_demos == len(demos) and found.recorded.n_inside == 0
    assert found.registration.is_identity and found.calibrated is None
    assert found.recorded.worst_clearance_m > 0.0
    assert 0.0 < found.recorded.hand_reach_m <= fit.HAND_REACH_M


def test_demos_without_a_skeleton_are_not_measured(robot, demos):
    assert fit.self_check(demos, robot) is None


def test_a_body_moved_into_the_robot_is_flagged_and_calibrated_back(robot, demos):
    clear = fit.measure(session(robot, demos))
    ev = session(robot, demos, (0.0, 0.25, 0.0))  # into the left arm's path
    moved = fit.measure(ev)
    assert not moved.fits and moved.n_inside > 0
    assert moved.parts and moved.parts[0].depth_m > fit.PENETRATION_TOLERANCE_M
    assert moved.parts[0].n_demos <= len(demos)
    assert any("inside the" in p for p in moved.problems())
    reg = fit.calibrate(ev)
    after = fit.measure(ev, reg)
    assert after.fits and after.worst_clearance_m >= -fit.FIT_PENETRATION_M - 1e-3
    assert reg.translation_m[1] < 0.0  # back out of the robot's path, against the perturbation
    assert np.linalg.norm(reg.translation_m) <= fit.MAX_CORRECTION_M
    # the smallest correction that fits: no further than the recording that fitted
    assert after.worst_clearance_m <= clear.worst_clearance_m + 0.01


def test_a_hand_away_from_the_gripper_is_flagged_and_calibrated_back(robot, demos):
    ev = session(robot, demos, (0.0, -0.15, 0.0))  # away from the robot: only the hand tells
    moved = fit.measure(ev)
    assert not moved.fits and moved.n_inside == 0 and moved.hand_reach_m > fit.HAND_REACH_M
    assert any("from the gripper" in p for p in moved.problems())
    reg = fit.calibrate(ev)
    after = fit.measure(ev, reg)
    assert after.fits and after.hand_reach_m <= fit.HAND_REACH_M + 1e-3
    assert reg.translation_m[1] > 0.0


def test_the_calibrated_body_keeps_its_radii_and_a_plan_through_it_is_refused(robot, demos):
    found = fit.self_check([with_skeleton(robot, d, (0.0, 0.25, 0.0)) for d in demos], robot)
    assert found is not None and not found.recorded.fits and found.fits
    shift = np.asarray(found.registration.translation_m)
    # a plan whose path crosses the calibrated body's chest: the observation's skeleton placed so
    # that the corrected registration puts its chest on the path
    t = np.arange(0.0, 1.0 + 1e-9, 0.01)
    qa, qb = np.array([0.0, -0.6, 0.0, 1.2, 0.0, 0.6, 0.0]), np.array([0.5, -0.2, 0.3, 0.7, 0.2, 0.9, 0.1])
    q = qa + t[:, None] * (qb - qa)
    motion = Trajectory(0.5 + t, q, np.tile(qb - qa, (t.size, 1)), np.zeros_like(q), NAMES)
    mid = ee_positions(robot, q[50:51])[0]
    obs = with_skeleton(robot, demos[0])
    torso = obs.extras[SKELETON_PREFIX + "/torso_1"][0]
    recorded = HumanMotion.from_demo(
        with_skeleton(robot, demos[0], mid - torso - shift), robot.settings.human
    )
    assert recorded is not None
    body = fit.registered(recorded, found.registration)
    assert np.array_equal(body.radius_m, recorded.radius_m)
    assert np.array_equal(body.radius_m, [p.radius_m for p in BODY_PARTS])
    verdict = HumanClearance(robot).check(motion, CheckContext(human=body))
    assert verdict.status == "fail" and verdict.measures.min_separation_m < 0.0


def test_registered_moves_tracked_frames_only(robot, demos):
    h = HumanMotion.from_demo(with_skeleton(robot, demos[0]), robot.settings.human)
    reg = fit.Registration((0.1, -0.2, 0.05))
    moved = fit.registered(h, reg)
    seen = np.isfinite(h.positions_m)
    assert np.array_equal(np.isfinite(moved.positions_m), seen)
    assert np.allclose((moved.positions_m - h.positions_m)[seen.all(axis=2)], [0.1, -0.2, 0.05])
    assumed = HumanMotion.assumed_human(robot.settings.human)
    assert fit.registered(assumed, reg) is assumed
    assert fit.registered(h, fit.Registration()) is h


def test_the_finding_round_trips_and_a_malformed_one_is_one_line(robot, demos):
    found = fit.self_check([with_skeleton(robot, d, (0.0, 0.25, 0.0)) for d in demos], robot)
    assert found is not None
    again = fit.HumanFit.from_json(found.to_json())
    assert again == found
    assert any("registration corrected by" in line for line in found.summary())
    bad = found.to_json() | {"translation_m": [0.0, float("nan"), 0.0]}
    with pytest.raises(DataError, match="human_fit"):
        fit.HumanFit.from_json(bad, "m.npz")


@pytest.fixture(scope="module")
def misfit_model(tiny, robot, demos):
    found = fit.self_check([with_skeleton(robot, d, (0.0, 0.25, 0.0)) for d in demos], robot, fit=False)
    assert found is not None and not found.fits
    return IProMP.load(tiny[1]).with_human_fit(found.to_json())


def test_a_misfit_model_is_warned_about_or_refused(misfit_model, tiny):
    warned: list[str] = []
    line = check_human_fit(misfit_model, "m.npz", False, warned.append)
    assert warned == [line] and line is not None and "does not fit" in line and "\n" not in line
    with pytest.raises(HumanModelMisfit, match="--strict-human"):
        check_human_fit(misfit_model, "m.npz", True, warned.append)
    # a model that fits, or was not measured, says nothing
    assert check_human_fit(IProMP.load(tiny[1]), "m.npz", True, warned.append) is None


def test_plan_strict_human_exits_3_with_one_line(misfit_model, tmp_path, capsys):
    path = tmp_path / "misfit.npz"
    misfit_model.save(path)
    out = tmp_path / "out"
    code = cli.main(["plan", str(path), str(tmp_path / "none.csv"), "--out", str(out), "--strict-human"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and len(err) == 1 and "does not fit" in err[0] and "--strict-human" in err[0]


def test_run_warns_about_a_misfit_model_and_refuses_it_with_strict_human(
    misfit_model, tiny, tmp_path, capsys
):
    path = tmp_path / "misfit.npz"
    misfit_model.save(path)
    ds, _ = tiny
    code = run_tiny((ds, path), tmp_path / "strict", "--strict-human")
    err = one_error_line(capsys.readouterr().err)
    assert code == 3 and "does not fit" in err and "--strict-human" in err
    assert not (tmp_path / "strict" / "report.json").exists()
    code = run_tiny((ds, path), tmp_path / "warned")
    captured = capsys.readouterr()
    assert code == 0, captured.err
    warned = [ln for ln in captured.err.splitlines() if "does not fit" in ln]
    assert len(warned) == 1 and "--strict-human" not in warned[0]
    report = (tmp_path / "warned" / "report.json").read_text()
    assert "human model does not fit" in report


def test_a_demo_whose_skeleton_is_refused_is_left_out_and_reported(robot, demos):
    good = [with_skeleton(robot, d) for d in demos[:4]]
    extras = dict(good[0].extras)
    extras[SKELETON_PREFIX + "/left_knee_1"] = np.full_like(extras[SKELETON_PREFIX + "/left_knee_1"], np.nan)
    bad = dataclasses.replace(good[0], extras=extras)
    found = fit.self_check([bad, *good[1:]], robot)
    assert found is not None and found.recorded.n_demos == 3
    assert len(found.refused) == 1 and "/left_knee_1" in found.refused[0]
    assert any("1 demos not measured" in line for line in found.summary())
    assert fit.HumanFit.from_json(found.to_json()) == found
