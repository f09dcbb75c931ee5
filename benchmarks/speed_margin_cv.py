"""Choose the contact-speed margin (``[iso15066] speed_margin``) by cross-validation on training demos.

Pool: the first ``--n-train`` demos of every task of a dataset with a tracked skeleton (recorded
order), as ``closed_loop_cv.py`` takes it. k-fold cross-validation over the pool: each fold trains
the model (with the robot's kinematics, as ``evaluate`` does) and derives the demonstrated limit
profile on the other folds, then replays its held-out demos in the closed loop at start ratios 0.1
and 0.2 with the human checks, for every candidate margin, and judges each commanded motion against
the recorded human (``ipromp_pin.evaluation.scorers.closed_loop.replay_scored``: contact-speed
violations beyond ``v_max`` itself, arrival delay with and without the human checks).

    python benchmarks/speed_margin_cv.py ../shared/datasets/handover_20171128
        [--observe /left_hand_1,emg] [--n-train 10] [--folds 5] [--jobs 2] [--json FILE]

``--smoke`` (no dataset): 4 synthetic demos per task (no skeleton: replayed without the human
checks), 2 folds, margins 0 and 0.1: seconds, what the test suite runs.

The rule (fixed before running it): the smallest margin with no violation over all held-out
replays; if none has none, the one with the fewest. Prints per candidate the violations, the replays
with any, the median hand-over error [cm] and the median arrival delay with / without the human [s].
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from ipromp_pin.data import parse_groups, skeleton_frames
from ipromp_pin.evaluation.scoring import replay_scored
from ipromp_pin.human import HumanMotion
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, conditioning_predictor, replay_demo
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot, load_robot_settings
from ipromp_pin.safety import HUMAN_CHECKS, CheckContext, CheckSuite

MARGINS = (0.0, 0.05, 0.1, 0.2)
RATIOS = (0.1, 0.2)


def _fold(args: tuple) -> list[dict]:
    fold, train, test, observe, margins, ratios, model_settings = args
    base = load_robot_settings("baxter_left")
    robots = {m: load_robot(replace(base, human=replace(base.human, speed_margin=m))) for m in margins}
    first = robots[margins[0]]
    motion_checks = CheckSuite.build(first, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    model = IProMP(observe=observe, **model_settings).fit(train, fk=partial(ee_positions, first))
    profile = demonstrated_profile(first, train, base.demonstrated_limits, "cv")
    rows = []
    for margin, robot in robots.items():
        suite = CheckSuite([*motion_checks.checks, *CheckSuite.build(robot, HUMAN_CHECKS).checks])
        for ratio in ratios:
            settings = ClosedLoopSettings(start_ratio=ratio)
            cond = conditioning_predictor(model, settings.condition_noise)
            for d in test:
                human = HumanMotion.from_demo(d, robot.settings.human)

                def replay(
                    checks: CheckSuite, context: CheckContext, demo=d, settings=settings, cond=cond, arm=robot
                ):
                    return replay_demo(model, arm, demo, profile, settings, checks, context, cond)

                used = suite if human is not None else suite.without(HUMAN_CHECKS)
                score, _ = replay_scored(replay, d, robot, used, CheckContext(human=human), human, False)
                rows.append(
                    {
                        "margin": margin,
                        "ratio": ratio,
                        "fold": fold,
                        "demo": d.name,
                        "violations": score.contact_speed_violations,
                        "err": score.handover_error_cm,
                        "delay": score.arrival_delay_s,
                        "delay_free": score.arrival_delay_without_human_s,
                    }
                )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path, nargs="?", help="dataset folder (not with --smoke)")
    parser.add_argument("--observe", default="/left_hand_1,emg")
    parser.add_argument("--n-train", type=int, default=10)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--smoke", action="store_true", help="synthetic demos, 2 margins, 2 folds: seconds")
    args = parser.parse_args()
    if args.dataset is None and not args.smoke:
        parser.error("the dataset is required (or --smoke)")
    robot = load_robot("baxter_left")
    margins, ratios, model_settings = MARGINS, RATIOS, {}
    if args.smoke:
        ds = make_synthetic_dataset(n_tasks=2, n_demos=4, seed=0)
        args.dataset, args.n_train, args.folds, args.observe = Path(ds.root), 4, 2, "orientation,emg"
        margins, ratios = (0.0, 0.1), (0.2,)
        model_settings = {"head": False, "handover": False, "coupling": "all", "noise": 10.0}
    else:
        ds = load_dataset(
            args.dataset,
            frames=skeleton_frames(parse_groups(args.observe)) or None,
            robot_joints=robot.settings.recorded_arm_joints,
            joint_limits=robot.recorded_joint_limits(),
            end_effector=partial(ee_positions, robot),
        )
    observe = parse_groups(args.observe)
    pool = {task: demos[: args.n_train] for task, demos in ds.demos.items()}
    work = []
    for fold in range(args.folds):
        test = [d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds == fold]
        train = [d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds != fold]
        work.append((fold, train, test, observe, margins, ratios, model_settings))
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("fork")) as ex:
            rows = [r for part in ex.map(_fold, work) for r in part]
    else:
        rows = [r for part in map(_fold, work) for r in part]
    print(f"{args.dataset.name}, observing {args.observe}: {args.folds}-fold CV on the first {args.n_train}")
    print("margin | replays | violations | replays with any | err [cm] | delay [s] | without human [s]")
    summary = []
    for m in margins:
        rs = [r for r in rows if r["margin"] == m]
        s = {
            "margin": m,
            "replays": len(rs),
            "violations": int(sum(r["violations"] or 0 for r in rs)),
            "replays_with_violations": int(sum(1 for r in rs if r["violations"])),
            "err": float(np.median([r["err"] for r in rs])),
            "delay": float(np.median([r["delay"] for r in rs])),
            "delay_free": float(
                np.median([r["delay_free"] for r in rs if r["delay_free"] is not None] or [np.nan])
            ),
        }
        summary.append(s)
        print(
            f"{m:g} | {s['replays']} | {s['violations']} | {s['replays_with_violations']} | {s['err']:.2f} "
            f"| {s['delay']:.2f} | {s['delay_free']:.2f}"
        )
    clean = [s for s in summary if s["violations"] == 0]
    chosen = clean[0] if clean else min(summary, key=lambda s: s["violations"])
    print(f"chosen: speed_margin = {chosen['margin']:g}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps({"summary": summary, "chosen": chosen["margin"], "rows": rows}, indent=1)
        )


if __name__ == "__main__":
    main()
