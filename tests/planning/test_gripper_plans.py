"""A model trained on gripper demos (issue 37 item 3): its robot side is a gripper pose path, the
quaternion signs made consistent before the Gaussian over the weights is fitted; planning with it
feeds the predicted poses (mean and samples) into the retargeting inverse kinematics of any arm,
then every check as for a model of joints; a model of gripper poses names no arm, so one must be
given."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers_cli import one_error_line

from ipromp_pin import plan
from ipromp_pin.app import main
from ipromp_pin.data import GRIPPER, ROBOT
from ipromp_pin.exceptions import ModelError
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.gripper_side import aligned_demos
from ipromp_pin.readers import write_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, gripper_kinematics, load_robot
from ipromp_pin.robot.recordings import as_gripper_demos, read_recordings
from ipromp_pin.signals.gripper import gripper_rotations

OBSERVE = ["orientation", "emg"]


def _negated(demo):
    g = demo.groups[GRIPPER].copy()
    g[:, 3:] *= -1.0
    return replace(demo, groups={**demo.groups, GRIPPER: g})


@pytest.fixture(scope="module")
def synthetic():
    baxter = load_robot("baxter_left")
    ds = make_synthetic_dataset(n_demos=10, seed=3)
    held = [ds.demos[t][0] for t in ds.tasks]
    joints = [d for d in ds.all_demos() if not any(d is h for h in held)]
    grip = as_gripper_demos(replace(ds, demos={t: ds.demos[t][1:] for t in ds.tasks}), baxter).all_demos()
    model_j = IProMP(observe=OBSERVE).fit(joints, **gripper_kinematics(baxter)._asdict())
    model_g = IProMP(observe=OBSERVE, robot_group=GRIPPER).fit(grip)
    return baxter, held, grip, model_j, model_g


def test_every_demo_is_turned_into_one_hemisphere_before_fitting(synthetic):
    _, _, grip, _, model_g = synthetic
    mixed = [_negated(d) if k % 2 else d for k, d in enumerate(grip)]
    aligned = [d for demos in aligned_demos({"all": mixed}).values() for d in demos]
    q = np.concatenate([d.groups[GRIPPER][:, 3:] for d in aligned])
    assert np.all(q @ q.mean(axis=0) > 0)  # one hemisphere
    flipped = IProMP(observe=OBSERVE, robot_group=GRIPPER).fit(mixed)
    z = np.linspace(0, 1, 21)
    for task in model_g.tasks_:  # the same model as from sign-consistent demos, up to the sign
        a, b = model_g.distribution(task, z)[0], flipped.distribution(task, z)[0]
        np.testing.assert_allclose(np.abs(a), np.abs(b), atol=1e-6)


def test_the_model_file_records_the_gripper_side(synthetic, tmp_path):
    _, held, _, _, model_g = synthetic
    model_g.save(tmp_path / "g.npz")
    back = IProMP.load(tmp_path / "g.npz")
    assert back.robot_group == GRIPPER and back.groups_[-1] == GRIPPER
    assert back.joint_names_ == ("x", "y", "z", "qx", "qy", "qz", "qw")
    obs = held[0].head(0.2, groups=OBSERVE)
    np.testing.assert_allclose(back.predict(obs).q_mean, model_g.predict(obs).q_mean)


def test_a_gripper_model_plans_on_the_panda_like_a_joint_model_retargeted(synthetic):
    baxter, held, _, model_j, model_g = synthetic
    panda = load_robot("panda")
    for demo in held:
        obs = demo.head(0.2, groups=OBSERVE)
        pg = plan(model_g, obs, panda, retreat=False)
        pj = plan(model_j, obs, panda, retreat=False)
        assert pg.passed and pj.passed, (pg.approach.failures, pj.approach.failures)
        r = pg.approach.retarget
        assert r is not None and r.from_poses and r.reached and r.to_dict()["source_path"] == "gripper_pose"
        # the arm's gripper at the hand-over is the model's predicted pose (renormalised)
        predicted = pg.approach.prediction.q_mean[-1]
        end = pg.approach.handover_pose
        assert np.linalg.norm(end[:3] - predicted[:3]) < 1.1e-3
        rot = gripper_rotations(np.vstack([end, predicted]))
        cos = (np.trace(rot[0].T @ rot[1]) - 1) / 2
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 0.55
        # the same hand-over as the joint model's, within a few cm (measured: benchmarks/gripper_demos.py)
        assert np.linalg.norm(end[:3] - pj.approach.handover_pose[:3]) < 0.03
        truth = ee_positions(baxter, demo.groups[ROBOT][-1:])[0]
        assert np.linalg.norm(end[:3] - truth) < 0.10
        samples = pg.approach.q_samples
        assert samples.shape[2] == panda.n_joints and np.ptp(samples[:, -1], axis=0).max() > 0


def test_baxter_executes_a_gripper_model_by_inverse_kinematics(synthetic):
    _, held, _, model_j, model_g = synthetic
    obs = held[1].head(0.2, groups=OBSERVE)
    pg = plan(model_g, obs, "baxter_left", retreat=False)
    assert pg.passed, pg.approach.failures
    assert pg.approach.retarget is not None and pg.approach.retarget.reached
    pj = plan(model_j, obs, "baxter_left", retreat=False)
    assert np.linalg.norm(pg.approach.handover_pose[:3] - pj.approach.handover_pose[:3]) < 0.03


def test_a_gripper_model_without_an_arm_is_refused(synthetic, tmp_path, capsys):
    _, held, grip, _, model_g = synthetic
    with pytest.raises(ModelError, match="name the arm that executes it with robot=NAME"):
        plan(model_g, held[0].head(0.2, groups=OBSERVE))
    model_g.save(tmp_path / "g.npz")
    write_dataset(replace(make_synthetic_dataset(n_tasks=1, n_demos=2), root="x"), tmp_path / "rec")
    rec = next((tmp_path / "rec").rglob("*.npz"))
    code = main(["plan", str(tmp_path / "g.npz"), str(rec), "--out", str(tmp_path / "plans")])
    assert code == 2
    assert "--robot NAME" in one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "plans").exists()


def test_a_task_added_to_a_gripper_model_is_aligned_with_it(synthetic):
    _, held, grip, _, _ = synthetic
    tasks = sorted({d.task for d in grip})
    base = IProMP(observe=OBSERVE, robot_group=GRIPPER).fit([d for d in grip if d.task != tasks[-1]])
    added = [_negated(d) for d in grip if d.task == tasks[-1]]  # the other hemisphere
    base.add_task(added)
    z = np.linspace(0, 1, 11)
    q_new = base.distribution(tasks[-1], z)[0][:, -4:]
    q_old = base.distribution(tasks[0], z)[0][:, -4:]
    assert float(np.mean(q_new @ q_old.mean(axis=0))) > 0  # same hemisphere as the model's


def test_on_handover_20171128_a_gripper_model_plans_on_the_panda_as_the_joint_model(handover2017_dir):
    baxter, panda = load_robot("baxter_left"), load_robot("panda")
    ds = read_recordings(handover2017_dir, baxter)
    ds = replace(ds, demos={t: d[:9] for t, d in ds.demos.items()})  # 9 demos per task: quicker
    held = [ds.demos[t][4] for t in ds.tasks]
    train = [d for d in ds.all_demos() if not any(d is h for h in held)]
    gds = as_gripper_demos(replace(ds, demos={"all": train}), baxter)
    model_g = IProMP(observe=OBSERVE, robot_group=GRIPPER).fit(gds.all_demos())
    model_j = IProMP(observe=OBSERVE).fit(train, **gripper_kinematics(baxter)._asdict())
    for demo in held:
        obs = demo.head(0.2, groups=OBSERVE)
        pg, pj = plan(model_g, obs, panda, retreat=False), plan(model_j, obs, panda, retreat=False)
        assert pg.passed, pg.approach.failures
        gap = np.linalg.norm(pg.approach.handover_pose[:3] - pj.approach.handover_pose[:3])
        assert gap < 0.03, (demo.name, gap)


def test_gripper_rotations_are_the_quaternions_rotations():
    from scipy.spatial.transform import Rotation

    q = Rotation.random(20, random_state=4).as_quat()  # x, y, z, w
    values = np.hstack([np.zeros((20, 3)), 1.003 * q])  # renormalised
    np.testing.assert_allclose(gripper_rotations(values), Rotation.from_quat(q).as_matrix(), atol=1e-12)


def test_the_hand_over_poses_of_gripper_demos_are_those_of_the_joints():
    from ipromp_pin.robot.reachability import handover_poses

    baxter = load_robot("baxter_left")
    joints = make_synthetic_dataset(n_tasks=1, n_demos=4).all_demos()
    grip = as_gripper_demos(make_synthetic_dataset(n_tasks=1, n_demos=4), baxter).all_demos()
    for a, b in zip(handover_poses(baxter, joints), handover_poses(baxter, grip), strict=True):
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-9)
