"""What the previews show of the human (outputs/human_preview.py): the recorded skeleton's capsules,
and the robot-body separation per control sample from the human checks' analysis, the robot held at
rest while the human still moves; the assumed human when the demo has no skeleton."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.human import SKELETON_PREFIX, HumanMotion
from ipromp_pin.human.separation import HAND_REGION, SeparationAnalyser
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.outputs.human_preview import held_until, human_tracks, judged_human
from ipromp_pin.preview.body import SEPARATION_STATES
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot


@pytest.fixture(scope="module")
def case():
    robot = load_robot("baxter_left")
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=3).all_demos()[0]
    h = HumanMotion.assumed_human(robot.settings.human, demo.t, demo.extras["hand_position"])
    extras = dict(demo.extras) | {SKELETON_PREFIX + f: h.positions_m[:, j] for j, f in enumerate(h.frames)}
    skeleton = dataclasses.replace(demo, extras=extras)
    q = demo.groups["robot"]
    names = tuple(robot.joint_names)
    motion = Trajectory(
        demo.t[:100], q[:100], np.gradient(q[:100], demo.t[:100], axis=0), np.zeros_like(q[:100]), names
    )
    return robot, demo, skeleton, motion


def test_the_human_shown_is_the_one_judged_else_the_assumed_one(case):
    robot, _, skeleton, _ = case
    recorded = HumanMotion.from_demo(skeleton, robot.settings.human)
    assert judged_human(robot, recorded) is recorded
    assumed = judged_human(robot, None)
    assert assumed.assumed and assumed.n_parts == recorded.n_parts


def test_the_robot_is_held_at_rest_while_the_human_moves(case):
    _, demo, _, motion = case
    held = held_until(motion, float(demo.t[-1]), 0.01)
    assert held.t_s[-1] == pytest.approx(demo.t[-1], abs=0.02) and held.dt_s == motion.dt_s
    np.testing.assert_array_equal(
        held.q[motion.n_samples :], np.repeat(motion.q[-1:], held.n_samples - motion.n_samples, 0)
    )
    assert not held.qd[motion.n_samples :].any()
    one = Trajectory(motion.t_s[:1], motion.q[:1], 0 * motion.qd[:1], 0 * motion.qdd[:1], motion.joint_names)
    assert np.allclose(np.diff(held_until(one, 1.0, 0.01).t_s), 0.01)
    assert held_until(motion, 0.0, 0.01) is motion


def test_tracks_follow_the_checks_analysis(case):
    robot, _, skeleton, motion = case
    human = HumanMotion.from_demo(skeleton, robot.settings.human)
    body, sep = human_tracks(robot, motion, human)
    assert body.n_parts == human.n_parts and body.t_s.size == human.t_s.size and not body.assumed
    assert sep.t_s[-1] == pytest.approx(human.t_s[-1], abs=0.02) and "recorded human" in sep.source
    full = held_until(motion, float(human.t_s[-1]), 0.01)
    ref = SeparationAnalyser(robot).analyse(full.t_s, full.q, full.qd, human)
    # human_clearance's measure: the closest part outside the hand
    np.testing.assert_allclose(sep.distance_m, np.maximum(ref.clearance_m(HAND_REGION), 0.0))
    assert sep.judged is not None and sep.judged.sum() == motion.n_samples
    assert [SEPARATION_STATES.index(s) for s in sep.state] == ref.state().tolist()
    clearance = ref.clearance_m(HAND_REGION)
    i = int(np.argmin(clearance))
    _, li, pi = ref.clearance_pairs(HAND_REGION)
    assert (sep.link[i], sep.body_part[i]) == (ref.links[li[i]], ref.parts[pi[i]])
    assert ref.regions[pi[i]] != HAND_REGION
    gap = float(np.linalg.norm(sep.robot_point_m[i] - sep.body_point_m[i]))
    assert clearance[i] <= 0 or gap == pytest.approx(clearance[i], abs=1e-6)
    assert human_tracks(robot, motion, None) == (None, None)
