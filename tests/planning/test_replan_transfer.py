"""The closed loop's retargeting through the gripper (:class:`ReplanTransfer`): a reference motion of
Baxter's left arm becomes a Panda's whose gripper follows Baxter's on the same timeline, the hand-over
exactly; consecutive re-plans stay on one branch; an unreachable hand-over is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.exceptions import UnreachableError
from ipromp_pin.motion.retarget import ReferenceMotion
from ipromp_pin.planning.transfer import ReplanTransfer
from ipromp_pin.promp.basis import GaussianBasis
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import frame_placements, load_robot
from ipromp_pin.robot.arm_transfer import TOL_M, TOL_RAD

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
    moved2, how2 = transfer.reference(later, q_now + 1.0, t_now)  # seeded by the last solution, not q_now
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
