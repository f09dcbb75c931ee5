"""``evaluate --closed-loop`` with the human: demos with a tracked skeleton are replayed with the
human checks (the planner knowing the human as observed until each re-plan), judged against the
RECORDED human motion, and replayed again without the human checks; demos without a skeleton keep
their cells as before, the new fields None."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.data import Dataset, Demo
from ipromp_pin.evaluation import closed_loop as evaluation_closed_loop
from ipromp_pin.evaluation.config import EvaluationConfig
from ipromp_pin.evaluation.scorers import closed_loop as scorer_module
from ipromp_pin.evaluation.scoring import human_measures
from ipromp_pin.evaluation.tables import closed_loop_markdown
from ipromp_pin.human import SKELETON_PREFIX, HumanMotion
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.closed_loop import ClosedLoopSettings
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot
from ipromp_pin.safety import HUMAN_CHECKS, Check, CheckContext, CheckSuite, Verdict
from ipromp_pin.safety.contact_speed import ContactSpeedMeasures
from ipromp_pin.safety.human_clearance import ClearanceMeasures

OBSERVE = ["orientation", "emg"]
SP_M = 0.35
"""The stand-in's protective separation distance [m]."""


def with_skeleton(demo: Demo, shift_m: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Demo:
    """``demo`` with a tracked skeleton, as the reader writes it (``skeleton:<frame>`` extras): the
    assumed standing human moved by ``shift_m`` [m], its handing hand on the demo's hand path."""
    h = HumanMotion.assumed_human(t_s=demo.t, hand_m=demo.extras["hand_position"])
    extras = dict(demo.extras)
    for j, f in enumerate(h.frames):
        extras[SKELETON_PREFIX + f] = h.positions_m[:, j] + (
            0.0 if f == "/left_hand_1" else np.asarray(shift_m)
        )
    return dataclasses.replace(demo, extras=extras)


class GripperSeparation(Check):
    """A stand-in human check: the gripper point's distance to the body outside the hand; inside
    ``SP_M`` the gripper speed must stay below ``limit`` [m/s] (asks for the slow-down that gives it)."""

    def __init__(self, robot, name: str, limit: float) -> None:
        super().__init__(robot)
        self.name = name  # type: ignore[misc]
        self.limit = limit
        self.horizons: list[tuple[float, float]] = []

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        human = context.human
        assert human is not None
        self.horizons.append((float(motion.t_s[0]), float(human.horizon_s)))
        p = ee_positions(self.robot, motion.q)
        a, b, r = human.capsules(motion.t_s)
        body = human.regions != "hand"
        d = b - a
        s = np.clip(
            np.einsum("npk,npk->np", p[:, None] - a, d) / np.maximum(np.einsum("npk,npk->np", d, d), 1e-12),
            0,
            1,
        )
        dist = np.linalg.norm(p[:, None] - (a + s[..., None] * d), axis=-1) - r
        dist_body = np.where(body[None], dist, np.inf)
        speed = np.r_[0.0, np.linalg.norm(np.diff(p, axis=0), axis=1) / max(motion.dt_s, 1e-9)]
        inside = dist.min(axis=1) < SP_M
        fast = inside & (speed > self.limit)
        k = int(np.argmin(dist_body.min(axis=1)))
        part = str(human.part_names[int(np.argmin(dist_body[k]))])
        within = float(inside.sum() * motion.dt_s)
        m: ClearanceMeasures | ContactSpeedMeasures
        if self.name == "human_clearance":
            m = ClearanceMeasures(
                float(dist_body.min()),
                "left_gripper",
                part,
                float(motion.t_s[k]),
                SP_M,
                within,
                0.0,
                "tracked",
            )
        else:
            ratio = float(speed[inside].max() / self.limit) if inside.any() else 0.0
            m = ContactSpeedMeasures(
                int(fast.sum()), int(fast.sum()), 1.0, ratio, "left_gripper", part, "chest",
                float(motion.t_s[k]), 0.0, None, None, None, within, "tracked",
            )  # fmt: skip
        if not fast.any():
            return Verdict(self.name, "pass", "", m)
        k_slow = float(speed[fast].max() / self.limit)
        return Verdict(self.name, "fail", f"{int(fast.sum())} samples too fast", m, slowdown=k_slow)


@pytest.fixture(scope="module")
def setup():
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    robot = load_robot("baxter_left")
    return IProMP(observe=OBSERVE).fit(train), robot, train, test, ds


def stand_ins(robot, limit: float = np.inf) -> list[GripperSeparation]:
    return [
        GripperSeparation(robot, HUMAN_CHECKS[0], limit),
        GripperSeparation(robot, HUMAN_CHECKS[1], limit),
    ]


EVALUATION_SUITE = scorer_module.evaluation_suite


def suite_with(robot, checks) -> CheckSuite:
    """The evaluation's checks without the human ones, and ``checks`` instead."""
    return CheckSuite([*EVALUATION_SUITE(robot, None, False).checks, *checks])


def replay_one(setup, demo, checks):
    model, robot, train, _, _ = setup
    profile = demonstrated_profile(robot, train)
    return scorer_module.replay_trials(
        model,
        robot,
        [demo],
        0.2,
        profile,
        ClosedLoopSettings(),
        suite_with(robot, checks),
        check_collisions=False,
    )[0]


def test_a_demo_without_skeleton_is_replayed_as_before(setup):
    _, robot, _, test, _ = setup
    checks = stand_ins(robot)
    plain = replay_one(setup, test[0], ())
    trial = replay_one(setup, test[0], checks)
    assert not checks[0].horizons  # no skeleton: the human checks never ran
    assert trial.closed_loop == plain.closed_loop
    row = scorer_module.compact(trial)
    assert row["closed_loop_human_min_separation_m"] is None
    assert row["closed_loop_arrival_delay_without_human_s"] is None


def test_a_demo_with_skeleton_is_judged_against_the_recorded_human(setup):
    _, robot, _, test, _ = setup
    demo = with_skeleton(test[0])
    checks = stand_ins(robot)
    trial = replay_one(setup, demo, checks)
    score = trial.closed_loop
    plain = replay_one(setup, test[0], ()).closed_loop
    # without a speed limit the human changes nothing: the same motion, the same delay
    assert score.arrival_delay_s == pytest.approx(plain.arrival_delay_s)
    assert score.arrival_delay_without_human_s == pytest.approx(plain.arrival_delay_s)
    # the planner knew the human until each re-plan; the judge knew all of it
    planned, judged = checks[0].horizons[:-1], checks[0].horizons[-1]
    assert planned and all(h <= t0 + 1e-9 for t0, h in planned)
    assert judged == (0.0, np.inf)
    human = HumanMotion.from_demo(demo)
    expected = human_measures(trial_trajectory(setup, demo), human, CheckSuite(stand_ins(robot)))
    assert score.human_min_separation_m == pytest.approx(expected.min_separation_m)
    assert score.protective_distance_time_s == pytest.approx(expected.protective_distance_time_s)
    assert score.contact_speed_violations == expected.contact_speed_violations == 0
    # finite and near: at the hand-over the gripper meets the hand, and the stand-in's gripper point
    # reaches the forearm's capsule beside it (the real check's hand region excludes it)
    assert -0.1 < score.human_min_separation_m < 1.0


def trial_trajectory(setup, demo):
    from ipromp_pin.planning.closed_loop import replay_demo

    model, robot, train, _, _ = setup
    settings = ClosedLoopSettings(start_ratio=0.2)
    suite = EVALUATION_SUITE(robot, None, False)
    return replay_demo(model, robot, demo, demonstrated_profile(robot, train), settings, suite).trajectory


def test_a_contact_speed_limit_slows_the_robot_and_costs_delay(setup):
    _, robot, _, test, _ = setup
    demo = with_skeleton(test[1], (-0.3, 0.0, 0.0))  # the human a step closer
    free = replay_one(setup, demo, stand_ins(robot)).closed_loop
    assert free.protective_distance_time_s > 0.2
    slow = replay_one(setup, demo, stand_ins(robot, limit=0.15)).closed_loop
    assert slow.arrival_delay_without_human_s == pytest.approx(free.arrival_delay_s)
    assert slow.arrival_delay_s > slow.arrival_delay_without_human_s + 0.05
    assert slow.contact_speed_violations < free.contact_speed_violations or free.contact_speed_violations == 0


def test_tiny_grid_cells_have_the_human_fields(setup, monkeypatch):
    _, robot, _, _, ds = setup
    monkeypatch.setattr(
        scorer_module,
        "evaluation_suite",
        lambda r, objects, human: suite_with(r, stand_ins(r) if human else []),
    )
    skeleton = Dataset("skeleton", {t: [with_skeleton(d) for d in demos] for t, demos in ds.demos.items()})
    config = EvaluationConfig(protocol="splits", observe=[OBSERVE], grid=[(4, 0.2)], n_test=2, n_splits=1)
    cells = evaluation_closed_loop.evaluate_closed_loop(skeleton, config, robot="baxter_left")
    assert len(cells) == 2
    for c in cells:
        trials = c.closed_loop_trials
        seps = [t["closed_loop_human_min_separation_m"] for t in trials]
        assert c.human_min_separation_m == pytest.approx(min(seps), abs=1e-4)
        assert c.contact_speed_violations == sum(t["closed_loop_contact_speed_violations"] for t in trials)
        without = [t["closed_loop_arrival_delay_without_human_s"] for t in trials]
        assert c.arrival_delay_without_human_s == pytest.approx(float(np.median(without)), abs=1e-3)
        assert c.protective_distance_time_s is not None and c.arrival_delay_s is not None
    md = closed_loop_markdown(cells)
    assert "### The human in the closed loop" in md and "contact-speed violations" in md
    plain = evaluation_closed_loop.evaluate_closed_loop(ds, config, robot="baxter_left")
    for c, p in zip(cells, plain, strict=True):
        assert p.human_min_separation_m is None and p.arrival_delay_without_human_s is None
        assert p.arrival_delay_s == pytest.approx(c.arrival_delay_s)  # no limit: the same replays
    plain_md = closed_loop_markdown(plain)
    assert "The human in the closed loop" not in plain_md
    assert "no replay above was checked against a human" in plain_md  # the figures say so
    assert "no replay above was checked against a human" not in md
