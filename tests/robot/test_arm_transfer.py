"""Retargeting through the gripper (issue 37): an arm with a [placement] in Baxter's scene follows
Baxter's gripper poses by inverse kinematics, every key of the placement is known or refused, and an
arm that cannot reach the hand-over is refused, never shifted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.exceptions import InfeasibleError, RobotError
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import frame_placements, load_robot, load_robot_settings, transfer_path
from ipromp_pin.robot.arm_transfer import TOL_M, TOL_RAD
from ipromp_pin.robot.rotations import geodesic_deg

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def placed_copy(tmp_path: Path, placement: str) -> Path:
    """panda.toml with its [placement] table replaced by ``placement``."""
    text = (ROBOTS / "panda.toml").read_text()
    start = text.index("\n[placement]") + 1
    end = text.index("[fixed_joints]")
    out = tmp_path / "panda_moved.toml"
    out.write_text(text[:start] + placement + "\n\n" + text[end:])
    return out


@pytest.fixture(scope="module")
def robots():
    return load_robot("baxter_left"), load_robot("panda")


@pytest.fixture(scope="module")
def baxter_paths():
    demos = make_synthetic_dataset(n_demos=3).all_demos()
    return [d.groups["robot"] for d in demos]


def test_the_placed_arm_s_base_is_where_the_placement_puts_it(robots):
    _, panda = robots
    s = panda.settings
    assert s.placement is not None and s.placement.source == "baxter_left"
    base = panda.model.getFrameId("panda_link0")
    data = panda.model.createData()
    pin.framesForwardKinematics(panda.model, data, panda.q_neutral)
    np.testing.assert_allclose(data.oMf[base].translation, s.placement.xyz_m, atol=1e-12)


def test_the_panda_s_gripper_follows_baxter_s_poses_within_the_tolerances(robots, baxter_paths):
    baxter, panda = robots
    for q in baxter_paths:
        moved = transfer_path(baxter, panda, q)
        assert moved.reached
        # independently of the solver's own residuals: both grippers through forward kinematics
        pb, rb = frame_placements(baxter, q)
        pp, rp = frame_placements(panda, moved.q)
        dist = np.linalg.norm(pb - pp, axis=1)
        angle = np.array([geodesic_deg(a, b) for a, b in zip(rb, rp, strict=True)])
        assert dist.max() <= TOL_M and angle.max() <= np.degrees(TOL_RAD)
        assert np.isclose(moved.max_path_residual_mm, dist.max() * 1e3, atol=1e-6)
        lo = panda.lower_rad + panda.settings.position_margin_rad
        hi = panda.upper_rad - panda.settings.position_margin_rad
        assert np.all(moved.q >= lo - 1e-12) and np.all(moved.q <= hi + 1e-12)
        # a continuous joint path: no jump to another IK branch between samples
        assert np.abs(np.diff(moved.q, axis=0)).max() < 0.2


def test_an_arm_placed_out_of_reach_does_not_reach_and_says_how_far(tmp_path, robots, baxter_paths):
    baxter, _ = robots
    far = load_robot(placed_copy(tmp_path, '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]'))
    moved = transfer_path(baxter, far, baxter_paths[0])
    assert not moved.reached
    assert moved.handover_residual_mm > 100
    assert "cannot reach the hand-over pose" in moved.why_not_reached(far)


def test_an_arm_without_placement_cannot_take_another_robot_s_path(robots, baxter_paths):
    baxter, _ = robots
    right = load_robot("baxter_right")
    with pytest.raises(InfeasibleError, match=r"no \[placement\]"):
        transfer_path(baxter, right, baxter_paths[0])


@pytest.mark.parametrize(
    "placement, message",
    [
        ('[placement]\nsource = "baxter_left"\nxyz_m = [5.0, 0.0, 0.0]', "placement.xyz_m"),
        ('[placement]\nsource = "baxter_left"\nxyz_m = [0.3, 0.2, -0.1]\nrpy_deg = [0, 0, 270]', "rpy_deg"),
        ('[placement]\nsource = "baxter_left"\nxyz = [0.3, 0.2, -0.1]', "did you mean 'xyz_m'"),
        ("[placement]\nxyz_m = [0.3, 0.2, -0.1]", "placement.source"),
        ('[placement]\nsource = "panda_moved"\nxyz_m = [0.3, 0.2, -0.1]', "another robot"),
    ],
)
def test_a_bad_placement_is_refused_naming_the_field(tmp_path, placement, message):
    with pytest.raises(RobotError, match=message):
        load_robot_settings(placed_copy(tmp_path, placement))


def test_the_start_configuration_is_the_one_the_motions_preferences_score_best(robots, tmp_path):
    from ipromp_pin.robot.arm_transfer import PoseSolver, kindest_start

    baxter = robots[0]
    # a UR5 placed where each of its start configurations can follow every synthetic motion (at its
    # shipped placement some cannot, and a configuration that follows more motions wins first)
    text = (ROBOTS / "ur5.toml").read_text()
    moved = tmp_path / "ur5_moved.toml"
    moved.write_text(text.replace("xyz_m = [0.10, 0.20, 0.10]", "xyz_m = [0.30, 0.20, 0.10]"))
    ur5 = load_robot(moved)
    demos = make_synthetic_dataset(n_demos=2).all_demos()
    pos, rot = frame_placements(baxter, np.stack([d.groups["robot"][0] for d in demos]))
    solver = PoseSolver(ur5)
    ends = solver.good_poses(rot[0], pos[0])
    assert len(ends) >= 3
    motions = [frame_placements(baxter, d.groups["robot"]) for d in demos]

    def only(k):  # every motion's preference rejects all but configuration k
        return lambda paths, samples: np.where(np.arange(len(paths)) == k, 0.0, -np.inf)

    for k in range(len(ends)):
        q = kindest_start(solver, rot[0], pos[0], [(p, r, only(k)) for p, r in motions])
        assert np.array_equal(q, ends[k][0])
    # the motions disagree: the configuration more of them accept wins
    votes = [(motions[0][0], motions[0][1], only(2)), *((p, r, only(1)) for p, r in motions)]
    assert np.array_equal(kindest_start(solver, rot[0], pos[0], votes), ends[1][0])
    # the preference sees each motion forward from the start: its first sample is the start pose
    seen = []
    kindest_start(
        solver,
        rot[0],
        pos[0],
        [(*motions[0], lambda paths, s: seen.append((paths, s)) or np.zeros(len(paths)))],
    )
    paths, samples = seen[0]
    assert samples[0] == 0 and np.all(np.diff(samples) > 0)
    assert np.allclose(paths[:, 0], np.stack([e[0] for e in ends]))


@pytest.mark.realdata
def test_a_preference_never_picks_a_configuration_whose_path_back_the_arm_cannot_follow(chen2017_dir, robots):
    from ipromp_pin.readers import read_demo
    from ipromp_pin.robot.arm_transfer import PoseSolver

    baxter = robots[0]
    kinova = load_robot("kinova_jaco2")
    # a recorded hand-over the Kinova meets in four configurations, two of them at the end of a path
    # it cannot follow back (its joints run into their limits: 11 cm off Baxter's gripper path)
    demo = read_demo(chen2017_dir / "aluminum_hold" / "csv" / "2017-07-11-15-20-19", "aluminum_hold")
    q = demo.groups["robot"][::3]
    pos, rot = frame_placements(baxter, q)
    ends = PoseSolver(kinova).good_poses(rot[-1], pos[-1])
    assert len(ends) >= 3
    kept = []
    for favourite in range(len(ends)):  # each configuration in turn the preferred one
        path = transfer_path(
            baxter, kinova, q, prefer=lambda paths, _s, f=favourite: -np.abs(np.arange(len(paths)) - f)
        )
        assert path.reached and path.max_path_residual_mm <= TOL_M * 1e3
        kept.append(any(np.abs(path.q[-1] - e[0]).max() < 1e-6 for e in ends[favourite : favourite + 1]))
    assert 0 < sum(kept) < len(ends)  # the followed ones keep their place, the others are passed over


def test_baxter_itself_has_no_placement():
    assert load_robot_settings("baxter_left").placement is None


def test_the_preferred_path_is_the_best_scored_of_the_hand_over_configurations_the_seeds_reach(robots):
    from ipromp_pin.robot.arm_transfer import GOOD_MARGIN, PoseSolver

    baxter = robots[0]
    ur5 = load_robot("ur5")  # six joints: isolated solutions (elbow, wrist, shoulder)
    q = make_synthetic_dataset(n_demos=3).all_demos()[0].groups["robot"]
    pos, rot = frame_placements(baxter, q)
    solver = PoseSolver(ur5)
    ends = solver.good_poses(rot[-1], pos[-1])
    assert len(ends) >= 2  # a UR5 meets a pose in several configurations
    for qe, err_p, err_r, _ in ends:
        assert err_p <= TOL_M and err_r <= TOL_RAD and solver.margin(qe) >= GOOD_MARGIN
    default = transfer_path(baxter, ur5, q)
    # a preference for the largest first joint at the hand-over
    chosen = transfer_path(baxter, ur5, q, prefer=lambda paths, _samples: paths[:, -1, 0])
    assert chosen.reached
    assert chosen.q[-1, 0] == pytest.approx(max(e[0][0] for e in ends), abs=1e-6)
    worst = transfer_path(baxter, ur5, q, prefer=lambda paths, _samples: -paths[:, -1, 0])
    assert worst.q[-1, 0] == pytest.approx(min(e[0][0] for e in ends), abs=1e-6)
    assert np.abs(chosen.q[-1] - worst.q[-1]).max() > 0.1
    assert default.reached and np.abs(np.diff(chosen.q, axis=0)).max() < 0.3  # followed back, no jump
