"""The compiled inverse kinematics (ipromp_pin.robot.ik_kernels, the kernel set "ik") equals its
reference, Pinocchio's PoseSolver: the same joint solutions, residuals and Jacobians on every shipped
placed arm, for the whole path, the sampled paths and an arm that cannot reach; its pieces (the serial
chain, log6 and its Jacobian) equal Pinocchio's; a failing compile falls back to the reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.promp import compiled
from ipromp_pin.promp.compiled import use_kernels
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import arm_chain as chain_module
from ipromp_pin.robot import frame_placements, ik_kernels, load_robot, transfer_path, transfer_samples
from ipromp_pin.robot.arm_chain import arm_chain, chain_placements
from ipromp_pin.robot.arm_transfer import PoseSolver

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
ARMS = ("panda", "ur5", "xarm7", "kinova_jaco2")
TOL = 1e-9


@pytest.fixture(scope="module")
def robots():
    """Every arm, built apart from load_robot's cache (which keeps the 8 last robots of the session)."""
    return {name: load_robot(name, cache=False) for name in ("baxter_left",) + ARMS}


@pytest.fixture(scope="module")
def baxter(robots):
    return robots["baxter_left"]


@pytest.fixture(scope="module")
def baxter_paths():
    return [d.groups["robot"] for d in make_synthetic_dataset(n_demos=2, seed=3).all_demos()[::2]]


def both(fn, *args):
    """``fn(*args)`` with Pinocchio's solver, then with the compiled kernels."""
    with use_kernels("numpy"):
        ref = fn(*args)
    with use_kernels("numba"):
        new = fn(*args)
    return ref, new


@pytest.mark.parametrize("name", ("baxter_left",) + ARMS)
def test_the_chain_read_from_the_model_gives_pinocchio_s_gripper_pose(name, robots):
    robot = robots[name]
    assert arm_chain(robot) is not None
    q = np.random.default_rng(1).uniform(robot.lower_rad, robot.upper_rad, size=(50, robot.n_joints))
    with use_kernels("numba"):
        pos, rot = chain_placements(robot, q)
    ref_pos, ref_rot = frame_placements(robot, q)
    np.testing.assert_allclose(pos, ref_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rot, ref_rot, rtol=0, atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 3e-4, 1e-2, 0.7, 2.5, np.pi - 1e-3, np.pi - 1e-7, np.pi])
def test_log6_and_its_jacobian_are_pinocchio_s_near_zero_and_near_pi(angle):
    rng = np.random.default_rng(int(angle * 1e3))
    for _ in range(5):
        axis = rng.normal(size=3)
        pose = pin.SE3(pin.exp3(axis / np.linalg.norm(axis) * angle), rng.normal(size=3))
        e, jac = np.empty(6), np.empty((6, 6))
        ik_kernels.log6(np.ascontiguousarray(pose.rotation), np.ascontiguousarray(pose.translation), e)
        ik_kernels.jlog6(np.ascontiguousarray(pose.rotation), np.ascontiguousarray(pose.translation), jac)
        np.testing.assert_allclose(e, pin.log6(pose).vector, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jac, pin.Jlog6(pose), rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ARMS)
def test_the_compiled_path_equals_pinocchio_s_on_every_placed_arm(name, robots, baxter, baxter_paths):
    arm = robots[name]
    for q in baxter_paths:
        ref, new = both(transfer_path, baxter, arm, q)
        assert ref.reached and new.reached
        np.testing.assert_allclose(new.q, ref.q, rtol=0, atol=TOL)
        np.testing.assert_allclose(new.position_error_m, ref.position_error_m, rtol=0, atol=1e-12)
        np.testing.assert_allclose(new.rotation_error_rad, ref.rotation_error_rad, rtol=0, atol=1e-12)
        np.testing.assert_allclose(new.jacobians, ref.jacobians, rtol=0, atol=TOL)
        # the samples of a prediction: the linearised step and the hand-overs solved exactly
        rng = np.random.default_rng(0)
        samples = q[None] + rng.normal(scale=0.02, size=(4,) + q.shape).cumsum(axis=1) * 0.1
        moved_ref, moved_new = both(transfer_samples, baxter, arm, samples, ref, q)
        np.testing.assert_allclose(moved_new, moved_ref, rtol=0, atol=TOL)


def test_an_arm_out_of_reach_is_refused_alike_with_the_same_residual(tmp_path, baxter, baxter_paths):
    text = (ROBOTS / "panda.toml").read_text()
    start, end = text.index("\n[placement]") + 1, text.index("[fixed_joints]")
    path = tmp_path / "panda_far.toml"
    path.write_text(
        text[:start] + '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]\n\n' + text[end:]
    )
    far = load_robot(path, cache=False)
    ref, new = both(transfer_path, baxter, far, baxter_paths[0])
    assert not ref.reached and not new.reached
    # every seed runs all its iterations far from the pose: agreement to rounding still
    np.testing.assert_allclose(new.q, ref.q, rtol=0, atol=1e-6)
    assert new.handover_residual_mm == pytest.approx(ref.handover_residual_mm, abs=1e-6)
    assert new.handover_residual_deg == pytest.approx(ref.handover_residual_deg, abs=1e-6)


def test_a_kinova_wrist_turned_past_a_half_turn_is_solved_as_pinocchio_solves_it(robots):
    """The Kinova's continuous joints are bounded to +-2 pi: a seed beyond pi on them."""
    kinova = robots["kinova_jaco2"]
    solver = PoseSolver(kinova)
    q_goal = solver.mid.copy()
    q_goal[[0, 3, 5]] += [2.5, -3.5, 4.0]
    pos, rot = frame_placements(kinova, q_goal)
    seed = q_goal + 0.05
    with use_kernels("numpy"):
        ref = PoseSolver(kinova).first_pose(rot[0], pos[0], seed)
    with use_kernels("numba"):
        new = PoseSolver(kinova).first_pose(rot[0], pos[0], seed)
    assert ref[1] <= 1e-3 and new[1] <= 1e-3
    np.testing.assert_allclose(new[0], ref[0], rtol=0, atol=TOL)
    assert abs(new[0][5] - q_goal[5]) < 1.0  # the wrist stays on its turn (not a turn away)


def test_a_failing_compile_falls_back_to_pinocchio_s_solver_and_says_so_once(
    monkeypatch, robots, baxter, baxter_paths
):
    from numba.core.errors import TypingError

    def broken(*_args):
        raise TypingError("cannot type this")

    heard: list[str] = []
    monkeypatch.setattr(chain_module, "_failed", {})
    monkeypatch.setattr(ik_kernels, "solve_first", broken)
    compiled.set_announcer(heard.append)
    try:
        panda = robots["panda"]
        with use_kernels("numpy"):
            ref = transfer_path(baxter, panda, baxter_paths[0])
        with use_kernels("numba"):
            new = transfer_path(baxter, panda, baxter_paths[0])
            again = transfer_path(baxter, panda, baxter_paths[0])
            assert chain_module.ik_kernels() is None  # the reference for the rest of the process
    finally:
        compiled.set_announcer(None)
    np.testing.assert_allclose(new.q, ref.q, rtol=0, atol=TOL)  # Pinocchio's own solutions
    np.testing.assert_array_equal(again.q, ref.q)  # the reference alone from then on
    assert len(heard) == 1 and "inverse-kinematics kernels failed (TypingError" in heard[0]


def test_the_warm_up_compiles_every_signature_the_retargeting_uses(robots, baxter, baxter_paths):
    from ipromp_pin.robot.ik_warmup import compile_kernels

    compile_kernels()
    before = {n: list(getattr(ik_kernels, n).signatures) for n in compiled.IK_KERNELS}
    assert all(before.values())
    panda = robots["panda"]
    with use_kernels("numba"):
        q = baxter_paths[0]
        path = transfer_path(baxter, panda, q)
        transfer_samples(baxter, panda, q[None] + 0.01, path, q)
    assert {n: list(getattr(ik_kernels, n).signatures) for n in compiled.IK_KERNELS} == before
