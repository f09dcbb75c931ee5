"""The closed loop's retargeting through the gripper (:class:`ReplanTransfer`): a reference motion of
Baxter's left arm becomes a Panda's whose gripper follows Baxter's on the same timeline, the hand-over
exactly; consecutive re-plans stay on one branch; an unreachable hand-over is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.exceptions import UnreachableError
from ipromp_pin.motion.limits import conservative_profile
from ipromp_pin.motion.retarget import ReferenceMotion
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.planning.transfer import ReplanTransfer
from ipromp_pin.promp.basis import GaussianBasis
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import frame_placements, load_robot
from ipromp_pin.robot.arm_transfer import TOL_M, TOL_RAD
from ipromp_pin.safety import CheckContext, CheckSuite, Verdict
from ipromp_pin.safety.base import Check

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
BASIS = GaussianBasis(31)  # the model's default basis


def baxter_reference(demo_index: int, shift: float = 0.0) -> ReferenceMotion:
    """A recorded synthetic Baxter path on the model's basis (``shift`` [rad] added to every joint at
    the end, growing along the motion: a changed prediction)."""
    demo = make_synthetic_dataset(n_tasks=1, n_demos=3, seed=0).all_demos()[demo_index]
    q = demo.groups["robot"]
    z = np.linspace(0.0, 1.0, len(q))
    q = q + shift * z[:, None]
    phi = np.exp(-0.5 * (z[:, None] - BASIS.centres) ** 2 / BASIS.width**2)
    w = np.linalg.solve(phi.T @ phi + 1e-6 * np.eye(BASIS.n_basis), phi.T @ q)
    n = q.shape[1]
    return ReferenceMotion(
        w.T, BASIS.centres, BASIS.width, np.ones(n), np.zeros(n), float(demo.t[-1] - demo.t[0])
    )


@pytest.fixture(scope="module")
def arms():
    return load_robot("baxter_left"), load_robot("panda")


def gripper_gap(source, target, ref_s: ReferenceMotion, ref_t: ReferenceMotion, t: np.ndarray):
    ps, rs = frame_placements(source, ref_s.evaluate(t, order=0)[0])
    pt, rt = frame_placements(target, ref_t.evaluate(t, order=0)[0])
    angle = np.arccos(np.clip((np.einsum("nij,nij->n", rs, rt) - 1.0) / 2.0, -1.0, 1.0))
    return np.linalg.norm(ps - pt, axis=1), angle


def test_the_panda_s_reference_follows_baxter_s_gripper_and_meets_the_hand_over_exactly(arms):
    baxter, panda = arms
    transfer = ReplanTransfer(baxter, panda)
    ref = baxter_reference(0)
    q0 = transfer.start(ref.evaluate(np.array([0.0]), order=0)[0][0])
    moved, how = transfer.reference(ref, q0, 0.3 * ref.duration_s)
    assert moved is not None and how.reached and how.source == "baxter_left"
    assert moved.weights.shape == (panda.n_joints, BASIS.n_basis) and moved.duration_s == ref.duration_s
    # at times the fit never saw too: within a few mm, and the reported residual close to the truth
    gap_m, angle = gripper_gap(baxter, panda, ref, moved, np.linspace(0.0, ref.duration_s, 503))
    assert gap_m.max() <= 5e-3 and angle.max() <= np.radians(2.0)
    assert 0.5 * gap_m.max() * 1e3 <= how.max_path_residual_mm <= gap_m.max() * 1e3 + 1e-6
    assert gap_m[-1] <= TOL_M and angle[-1] <= TOL_RAD  # the hand-over within the reach tolerance
    assert how.handover_residual_mm == pytest.approx(gap_m[-1] * 1e3, abs=1e-6)
    assert how.handover_residual_mm <= how.max_path_residual_mm
    lo, hi = panda.lower_rad, panda.upper_rad
    q = moved.evaluate(np.linspace(0.0, ref.duration_s, 101), order=0)[0]
    assert np.all(q >= lo) and np.all(q <= hi)
    d = how.to_dict()
    assert d["source_robot"] == "baxter_left" and d["reached"] is True
    assert d["max_path_residual_mm"] == pytest.approx(how.max_path_residual_mm, abs=1e-3)


def test_the_first_re_plan_starts_at_the_commanded_configuration_and_the_next_stay_on_its_branch(arms):
    baxter, panda = arms
    ref = baxter_reference(1)
    t_now = 0.25 * ref.duration_s
    q_src_now = ref.evaluate(np.array([t_now]), order=0)[0][0]
    transfer = ReplanTransfer(baxter, panda)
    q_now = transfer.start(q_src_now)  # the arm's configuration where Baxter's gripper is now
    moved, _ = transfer.reference(ref, q_now, t_now)
    assert moved is not None
    assert np.abs(moved.evaluate(np.array([t_now]), order=0)[0][0] - q_now).max() < 0.05
    later = baxter_reference(1, shift=0.05)  # the next re-plan predicts a slightly different motion
    # the arm's configuration given as another solution of the same gripper pose: the next re-plan is
    # seeded by the last solution, not by it
    pos, rot = frame_placements(panda, q_now[None])
    alts = [a[0] for a in transfer.solver.good_poses(rot[0], pos[0])]
    q_alt = max(alts, key=lambda q: float(np.abs(q - q_now).max()))
    assert np.abs(q_alt - q_now).max() > 0.3
    moved2, how2 = transfer.reference(later, q_alt, t_now)
    assert moved2 is not None and how2.reached
    t = np.linspace(0.0, ref.duration_s, 50)
    step = np.abs(moved2.evaluate(t, order=0)[0] - moved.evaluate(t, order=0)[0]).max()
    assert step < 0.2  # the same branch: a small change of the motion moves the joints a little


def test_an_unreachable_hand_over_is_refused_and_keeps_the_last_solution(arms, tmp_path):
    baxter, _ = arms
    text = (ROBOTS / "panda.toml").read_text()
    start, end = text.index("\n[placement]") + 1, text.index("[fixed_joints]")
    far = tmp_path / "panda_far.toml"
    far.write_text(
        text[:start] + '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]\n\n' + text[end:]
    )
    far_panda = load_robot(str(far))
    transfer = ReplanTransfer(baxter, far_panda)
    ref = baxter_reference(0)
    moved, how = transfer.reference(ref, np.zeros(far_panda.n_joints), 0.5)
    assert moved is None and not how.reached
    assert how.handover_residual_mm > TOL_M * 1e3
    assert "cannot reach the predicted hand-over pose" in transfer.why_not_reached(how)
    with pytest.raises(UnreachableError, match="cannot reach the recorded start pose"):
        transfer.start(ref.evaluate(np.array([0.0]), order=0)[0][0])


def test_a_restarted_re_plan_starts_where_the_arm_s_gripper_is_and_joins_the_path_by_the_hand_over(arms):
    baxter, panda = arms
    ref = baxter_reference(1)
    transfer = ReplanTransfer(baxter, panda)
    # the arm still rests at the motion's start while the prediction has moved on by a quarter
    q_now = transfer.start(ref.evaluate(np.array([0.0]), order=0)[0][0])
    t_now = 0.25 * ref.duration_s
    plain, _ = transfer.reference(ref, q_now, t_now)  # a first re-plan: the predicted path as it is
    assert plain is not None
    moved, how = transfer.reference(ref, q_now, t_now, restart=True)  # that one refused: restarted
    assert moved is not None and how.reached
    p_now, _ = frame_placements(panda, q_now[None])
    p_ref, _ = frame_placements(baxter, ref.evaluate(np.array([t_now]), order=0)[0])
    assert np.linalg.norm(p_now[0] - p_ref[0]) > 0.02  # the prediction is elsewhere by now
    # the restarted reference starts at the arm's configuration (its gripper where it is), the plain
    # one at the prediction
    assert np.abs(moved.evaluate(np.array([t_now]), order=0)[0][0] - q_now).max() < 0.02
    p_plain, _ = frame_placements(panda, plain.evaluate(np.array([t_now]), order=0)[0])
    assert np.linalg.norm(p_plain[0] - p_ref[0]) < 0.005
    # and meets the predicted hand-over pose exactly
    gap_m, angle = gripper_gap(baxter, panda, ref, moved, np.array([ref.duration_s]))
    assert gap_m[0] <= TOL_M and angle[0] <= TOL_RAD


def test_the_offset_of_a_warped_pose_path_fades_from_the_given_phase_to_none_at_the_end():
    from scipy.spatial.transform import Rotation

    from ipromp_pin.planning.transfer import fade_out, warped_poses

    z = np.linspace(0.0, 1.0, 41)
    keep = fade_out(z, 0.25)
    assert np.all(keep[z <= 0.25] == 1.0) and keep[-1] == 0.0 and np.all(np.diff(keep) <= 0.0)
    rng = np.random.default_rng(3)
    pos = rng.normal(size=(41, 3))
    rot = Rotation.random(41, random_state=4).as_matrix()
    dp, dr = np.array([0.1, -0.2, 0.05]), np.array([0.0, 0.3, -0.1])
    wp, wr = warped_poses(pos, rot, keep, dp, dr)
    np.testing.assert_allclose(wp[:10], pos[:10] + dp)  # the whole offset up to the phase
    np.testing.assert_allclose(wr[5], rot[5] @ Rotation.from_rotvec(dr).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(wp[-1], pos[-1]) and np.testing.assert_allclose(wr[-1], rot[-1], atol=1e-12)


class _RefuseEarly(Check):
    """Refuses every motion that starts before ``until_s`` [s] (asks for no slow-down)."""

    name = "refuse_early"
    until_s = 0.0

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        if motion.t_s[0] < self.until_s:
            return Verdict(self.name, "fail", f"starts at {motion.t_s[0]:.2f} s")
        return Verdict(self.name, "pass", f"starts at {motion.t_s[0]:.2f} s")


def test_an_arm_not_moved_yet_restarts_from_its_gripper_after_a_refused_re_plan(synthetic_closed_loop):
    model, baxter, _train, test = synthetic_closed_loop
    panda = load_robot("panda")
    demo = test[0]
    check = _RefuseEarly(panda)
    check.until_s = 0.4 * float(demo.t[-1] - demo.t[0])
    settings = ClosedLoopSettings(start_ratio=0.2)
    suite = CheckSuite([check])
    result = replay_demo(model, panda, demo, conservative_profile(panda), settings, suite, source=baxter)
    moves = [r for r in result.replans if r.retarget is not None]
    first = next(i for i, r in enumerate(moves) if r.committed)
    assert first >= 2  # some re-plans refused before the first committed one
    restarted = [r.retarget["restarted"] for r in moves]
    assert restarted[0] is False  # the first follows the predicted path as it is
    # then, until one is committed, from the arm's gripper after each plain one refused (alternately)
    assert restarted[1 : first + 1] == [i % 2 == 1 for i in range(1, first + 1)]
    assert not any(restarted[first + 1 :])  # moving: tracked as before
    # the committed motion leaves the rest configuration without a jump
    q = result.trajectory.q
    assert np.abs(np.diff(q, axis=0)).max() < 0.05
