"""Choosing how a placed arm meets the hand-over (issue 37: redundancy used to stay away from the
human): of the candidate paths, :func:`kindest_to_human` keeps those as clear of the body as the
clearest, then prefers the one expected to take the least time."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.planning.transfer import CLEARANCE_TIE_M, kindest_to_human
from ipromp_pin.robot import load_robot
from ipromp_pin.safety import CheckContext, CheckSuite


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")  # six joints: a few isolated configurations per gripper pose


def test_paths_clearly_closer_to_the_body_than_the_clearest_are_never_preferred(ur5):
    suite = CheckSuite.build(ur5)
    t = np.linspace(0.5, 3.0, 30)
    prefer = kindest_to_human(suite, CheckContext(), t)  # the assumed human
    assert prefer is not None
    mid = 0.5 * (ur5.lower_rad + ur5.upper_rad)
    turns = np.linspace(-1.5, 1.5, 7)  # the whole arm turned toward or away from the human
    paths = np.repeat(np.repeat(mid[None, None], 30, axis=1), turns.size, axis=0)
    paths[:, :, 0] += turns[:, None]
    scores = prefer(paths, np.arange(t.size))
    check = suite.get("human_clearance")
    human = check.human(CheckContext())
    clear = np.array(
        [
            check.analyser.analyse(t.copy(), p.copy(), np.zeros_like(p), human).clearance_m().min()
            for p in paths
        ]
    )
    assert np.ptp(clear) > 2 * CLEARANCE_TIE_M  # some turns clearly closer than others
    np.testing.assert_array_equal(np.isfinite(scores), clear >= clear.max() - CLEARANCE_TIE_M)


def test_of_equally_clear_paths_the_one_with_less_joint_travel_is_preferred(ur5):
    suite = CheckSuite.build(ur5)
    t = np.linspace(0.5, 3.0, 30)
    prefer = kindest_to_human(suite, CheckContext(), t)
    mid = 0.5 * (ur5.lower_rad + ur5.upper_rad)
    still = np.repeat(mid[None], 30, axis=0)
    wrist = still.copy()
    wrist[:, 5] += 1.5 * np.sin(np.linspace(0.0, np.pi, 30))  # the flange turns and back: 3 rad travel
    scores = prefer(np.stack([still, wrist]), np.arange(t.size))
    assert np.all(np.isfinite(scores)) and scores[0] > scores[1]


def test_without_a_human_check_or_for_a_redundant_arm_nothing_is_preferred(ur5):
    suite = CheckSuite.build(ur5, exclude=["human_clearance"])
    assert kindest_to_human(suite, CheckContext(), np.linspace(0.0, 1.0, 5)) is None
    panda = load_robot("panda")  # seven joints: a continuum of configurations, the first one kept
    assert kindest_to_human(CheckSuite.build(panda), CheckContext(), np.linspace(0.0, 1.0, 5)) is None


def test_a_replay_s_start_motions_are_the_tasks_prior_paths_scored_against_the_human_at_the_start(
    ur5, synthetic_closed_loop
):
    from ipromp_pin.planning.transfer import start_motions
    from ipromp_pin.robot.arm_transfer import SCORED_SAMPLES

    model, baxter, train, _ = synthetic_closed_loop
    motions = start_motions(model, CheckSuite.build(ur5), CheckContext())
    assert len(motions) == len(model.tasks_)
    for task, (q, prefer) in zip(model.tasks_, motions, strict=True):
        assert q.shape == (SCORED_SAMPLES, baxter.n_joints)
        starts = np.stack([d.groups["robot"][0] for d in train if d.task == task])
        assert np.abs(q[0] - starts.mean(axis=0)).max() < 0.1  # the prior starts where the demos do
        mid = 0.5 * (ur5.lower_rad + ur5.upper_rad)
        assert np.isfinite(prefer(np.repeat(mid[None, None], 3, axis=1), np.arange(3))).all()
    assert start_motions(model, CheckSuite.build(ur5, exclude=["human_clearance"]), CheckContext()) == []
    assert start_motions(model, CheckSuite.build(load_robot("panda")), CheckContext()) == []
    assert start_motions(model, None, CheckContext()) == []
