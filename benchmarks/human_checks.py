"""Benchmark: the human checks (human_clearance, contact_speed) on the one-shot plan of every demo.

Every demo of the dataset is planned once by a model that did not see it (``--folds`` folds: the
model of a fold is trained on the other folds' demos), observing ``--observe`` for the first
``--ratio`` of the demo, like ``ipromp-pin run``. Per plan:

* *before*: the plan timed without the human checks, checked against the human as the planner knows
  it (the tracked skeleton until the end of the observation, then held and growing at the human
  speed; the assumed human without a skeleton) and against the recorded human (what happened);
* *after*: the plan of ``plan(..., suite)`` with the human checks, re-timed when a failing check asks for a
  slower motion (only where it asks when that passes, else uniformly); its delay (the longer duration),
  and its checks against the recorded human.

Prints the share of plans failing each human check before and after the re-timing, the delays and
the cost of the two checks on a whole plan (per plan the median of 5 runs, then the median over
plans, in ms; the machine may be shared).

    python benchmarks/human_checks.py [--dataset ../shared/datasets/handover_20171128]
        [--observe /left_hand_1,emg] [--folds 5] [--ratio 0.2] [--handing-arm predicted|held]
        [--json FILE]

``--handing-arm``: ``predicted`` (default) calibrates each fold's forecast of the body on its
training demos (:mod:`ipromp_pin.planning.human_forecast`) and plans against it; ``held`` holds the
body where last seen.

``--smoke``: 2 synthetic tasks, 4 demos each, 2 folds: seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import json
import time
from functools import partial
from pathlib import Path

import numpy as np

from ipromp_pin.data import parse_groups, skeleton_frames
from ipromp_pin.human import HumanMotion
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.human_forecast import with_forecast
from ipromp_pin.planning.one_shot import plan
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, gripper_rotations, load_robot
from ipromp_pin.safety import CheckContext, CheckSuite

NAMES = ("human_clearance", "contact_speed")
REPEATS = 5
"""Timed runs of the two checks per plan (their median is the plan's cost)."""


def _human(demo, settings) -> HumanMotion:
    human = HumanMotion.from_demo(demo, settings)
    if human is None:
        human = HumanMotion.assumed_human(settings, demo.t, demo.extras.get("hand_position"))
    return human


def _one(model, robot, checks, demo, observe, ratio) -> dict:
    obs = demo.head(ratio, groups=observe)
    t_end = float(obs.t[-1] - obs.t[0])
    recorded = _human(demo, robot.settings.human)
    known = recorded.until(float(obs.t[-1]))
    base = plan(model, robot, obs, CheckSuite([]), check_joints=False)
    motion = base.trajectory  # on the human's clock, from the end of the observation
    assert abs(motion.start_s - t_end) < 1e-9
    before = checks.run(motion, CheckContext(human=known))
    costs = []
    for _ in range(REPEATS):  # a fresh motion each time: the analyser keeps only the last result
        again = Trajectory(motion.t_s.copy(), motion.q, motion.qd, motion.qdd, motion.joint_names)
        t0 = time.perf_counter()
        checks.run(again, CheckContext(human=known))
        costs.append((time.perf_counter() - t0) * 1e3)
    cost_ms = float(np.median(costs))
    truth = checks.run(motion, CheckContext(human=recorded))
    after = plan(model, robot, obs, checks, CheckContext(human=known), check_joints=False)
    truth_after = checks.run(after.trajectory, CheckContext(human=recorded))
    out = {
        "demo": f"{demo.task}/{demo.name}",
        "human": known.label,
        "n_samples": motion.n_samples,
        "cost_ms": cost_ms,
        "slowdown": float(after.slowdown),
        "delay_s": float(after.slowdown_delay_s),
        "local": bool(after.slowdown_local),
    }
    for r, r_true, r_after in zip(before, truth, truth_after, strict=True):
        out[f"{r.name}_before"] = r.passed
        out[f"{r.name}_recorded"] = r_true.passed
        out[f"{r.name}_after"] = after.checks[r.name].passed
        out[f"{r.name}_recorded_after"] = r_after.passed
        out[f"{r.name}_values"] = {
            k: v for k, v in r.measures.to_dict().items() if isinstance(v, float | int | str)
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--dataset", type=Path, default=Path("../shared/datasets/handover_20171128"))
    parser.add_argument("--observe", default="/left_hand_1,emg")
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--ratio", type=float, default=0.2)
    parser.add_argument("--handing-arm", choices=("predicted", "held"), default="predicted")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--smoke", action="store_true", help="2 synthetic tasks, 4 demos, 2 folds: seconds")
    args = parser.parse_args()
    robot = load_robot("baxter_left")
    if args.smoke:
        observe, args.folds = ["orientation", "emg"], 2
        ds = make_synthetic_dataset(n_tasks=2, n_demos=4, seed=0)
    else:
        observe = parse_groups(args.observe)
        ds = load_dataset(
            args.dataset,
            frames=skeleton_frames(observe) or None,
            robot_joints=robot.settings.recorded_arm_joints,
            joint_limits=robot.recorded_joint_limits(),
            end_effector=partial(ee_positions, robot),
        )
    demos = ds.all_demos()
    checks = CheckSuite.build(robot, NAMES)
    rows = []
    smoke_model = {"head": False, "handover": False, "coupling": "all"} if args.smoke else {}
    for f in range(args.folds):
        test = demos[f :: args.folds]
        train = [d for d in demos if all(d is not x for x in test)]
        model = IProMP(observe=observe, **smoke_model).fit(
            train, fk=partial(ee_positions, robot), fk_rot=partial(gripper_rotations, robot)
        )
        if args.handing_arm == "predicted":
            model = with_forecast(model, train, robot.settings.human)
        for demo in test:
            rows.append(_one(model, robot, checks, demo, observe, args.ratio))
            r = rows[-1]
            print(f"{r['demo']:40s} {r['human']:8s} clear {r['human_clearance_before']!s:5} "
                  f"speed {r['contact_speed_before']!s:5} -> {r['contact_speed_after']!s:5} "
                  f"k {r['slowdown']:.2f} {r['delay_s']:+.2f} s {'local' if r['local'] else ''}  "
                  f"{r['cost_ms']:.1f} ms")  # fmt: skip
    _summary(rows)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


def _summary(rows: list[dict]) -> None:
    n = len(rows)

    def share(key: str, name: str | None = None) -> str:
        names = NAMES if name is None else (name,)
        k = sum(not all(r[f"{m}_{key}"] for m in names) for r in rows)
        return f"{k}/{n} ({k / n:.0%})"

    print(f"plans: {n} ({', '.join(sorted({r['human'] for r in rows}))} human)")
    for key, what in (("before", "planner's human, before re-timing"), ("after", "after re-timing"),
                      ("recorded", "recorded human, before re-timing"),
                      ("recorded_after", "recorded human, after re-timing")):  # fmt: skip
        print(f"failing the human checks ({what}): {share(key)}; human_clearance {share(key, NAMES[0])}, "
              f"contact_speed {share(key, NAMES[1])}")  # fmt: skip
    slowed = [r for r in rows if r["slowdown"] != 1.0]
    delays = np.array([r["delay_s"] for r in slowed]) if slowed else np.zeros(1)
    local = sum(r["local"] for r in slowed)
    print(
        f"re-timed plans: {len(slowed)}/{n} ({local} only where the checks ask, the rest uniformly); "
        f"delay median {np.median(delays):.2f} s, max {delays.max():.2f} s"
    )
    cost = np.array([r["cost_ms"] for r in rows])
    samples = np.array([r["n_samples"] for r in rows])
    print(f"cost of both checks per plan: median {np.median(cost):.1f} ms (max {cost.max():.1f} ms), "
          f"median {np.median(samples):.0f} samples")  # fmt: skip


if __name__ == "__main__":
    main()
