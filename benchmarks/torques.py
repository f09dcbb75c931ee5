"""Benchmark: joint torques of the plans on the shared recordings, before and after torque-aware timing.

The model is trained on the first ``--n-train`` demos of every task; every other demo is observed for
its first ``--ratio`` and planned for:

* one-shot (``plan``, the robot settings' limits): the plan as it was before the joint-torque check
  (velocity/acceleration timing only, no check), the same path with the check (re-timed slower when it
  asks), and with toppra's joint-torque constraint in the timing too (``torque_timing``, the default
  of ``ipromp-pin run``); the payload is the recognised task's object of the shipped
  ``robots/objects.toml``;
* closed loop (``replay_demo``, demonstrated limits, ``--closed-loop``): without and with the check
  on every re-plan, the check then run on the whole commanded trajectory.

Prints per variant: how many plans exceed the allowed torques (``1 - effort_margin`` of the URDF's
effort limits), the median and largest peak torque ratio, and the median arrival delay against the
plan without the check; and the median wall time of the check (a whole one-shot plan) and of
torque-aware timing.

    PYTHONPATH=. python benchmarks/torques.py --dataset ../shared/datasets/chen2017_handover [--closed-loop]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin.exceptions import InfeasibleError
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.planning.one_shot import plan
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot
from ipromp_pin.robot.objects import load_objects
from ipromp_pin.safety import CheckContext, CheckSuite, TimingConstraints
from ipromp_pin.safety.joint_torques import JointTorques


def summary(name: str, ratios: list[float], allowed: float, delays: list[float] | None = None) -> str:
    r = np.array(ratios)
    text = (
        f"{name:<34} {int((r > allowed + 1e-9).sum()):>3}/{r.size:<3} over; peak ratio median "
        f"{np.median(r):.2f}, max {r.max():.2f}"
    )
    if delays:
        d = np.array(delays)
        text += f"; arrival delay median {np.median(d):+.3f} s, max {d.max():+.3f} s"
    return text


class UntimedTorques(JointTorques):
    """The joint-torque check without its toppra constraint (the plan is only re-timed slower)."""

    def timing_constraints(self, context: CheckContext) -> TimingConstraints:
        return TimingConstraints()


def peak(check: JointTorques, motion, context, verdict=None) -> float:
    """The check's peak |torque| / effort limit of ``motion`` (or of a verdict already made)."""
    v = verdict if verdict is not None else check.check(motion, context)
    return float(v.measures.peak_torque_ratio)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--dataset", type=Path, default=None, help="real dataset (default: synthetic)")
    parser.add_argument("--n-train", type=int, default=10)
    parser.add_argument("--ratio", type=float, default=0.2)
    parser.add_argument("--max-tests", type=int, default=1000)
    parser.add_argument("--closed-loop", action="store_true")
    parser.add_argument("--objects", type=Path, default=None, help="task file (default: the shipped one)")
    parser.add_argument(
        "--no-springs", action="store_true", help="the URDF's RNEA without Baxter's s1 springs"
    )
    parser.add_argument("--smoke", action="store_true", help="2 synthetic tasks, 4 demos, 2 tests: seconds")
    args = parser.parse_args()
    if args.smoke:
        args.dataset, args.n_train, args.max_tests, args.closed_loop = None, 4, 2, True
    if hasattr(os, "sched_setaffinity"):  # one core, as benchmarks/closed_loop.py
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    robot = load_robot("baxter_left")
    if args.dataset is None:
        ds = make_synthetic_dataset(n_tasks=2 if args.smoke else 3, n_demos=args.n_train + 10, seed=0)
    else:
        ds = load_dataset(
            args.dataset,
            robot_joints=robot.settings.recorded_arm_joints,
            joint_limits=robot.recorded_joint_limits(),
            end_effector=lambda q: ee_positions(robot, q),
        )
    observe = ["orientation", "emg"]
    train = [d for demos in ds.demos.values() for d in demos[: args.n_train]]
    test = [d for demos in ds.demos.values() for d in demos[args.n_train :]][: args.max_tests]
    objects = load_objects(args.objects)
    check = JointTorques(robot, springs=not args.no_springs)
    untimed = UntimedTorques(robot, springs=not args.no_springs)
    motion_checks = CheckSuite.build(robot, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    allowed = 1.0 - robot.settings.effort_margin
    rows: dict[str, list[float]] = {"before": [], "check": [], "torque_timing": []}
    delays: dict[str, list[float]] = {"check": [], "torque_timing": []}
    ms: dict[str, list[float]] = {"check": [], "time_path_plain": [], "time_path_torque": []}
    failed = 0
    with threadpool_limits(limits=1):
        smoke_model = {"head": False, "handover": False, "coupling": "all"} if args.smoke else {}
        model = IProMP(observe=observe, **smoke_model).fit(train, fk=lambda q: ee_positions(robot, q))
        for d in test:
            obs = d.head(args.ratio, groups=observe)
            try:
                base = plan(model, robot, obs, CheckSuite([]), check_joints=False)
                ctx = CheckContext(objects=objects, task=base.prediction.task)
                motion = base.trajectory  # on the human's clock
                t0 = time.perf_counter()
                rows["before"].append(peak(check, motion, ctx))
                ms["check"].append((time.perf_counter() - t0) * 1e3)
                for key, tt in (("check", False), ("torque_timing", True)):
                    suite = CheckSuite([check if tt else untimed])
                    res = plan(model, robot, obs, suite, CheckContext(objects=objects), check_joints=False)
                    rows[key].append(peak(check, res.trajectory, None, res.checks["joint_torques"]))
                    delays[key].append(float(res.trajectory.end_s - base.trajectory.end_s))
                    ms["time_path_torque" if tt else "time_path_plain"].append(
                        res.timing_report.timings_ms.get("total_ms", np.nan)
                    )
            except InfeasibleError:
                failed += 1
        print(
            f"data: {args.dataset or 'synthetic'}; {len(train)} training demos, {len(test)} test demos, "
            f"observed {args.ratio:.0%}; allowed peak ratio {allowed:.2f} (shared machine)"
        )
        print(f"one-shot plans ({failed} not timeable):")
        print(summary("  before (no torque check)", rows["before"], allowed))
        print(summary("  with the check (re-timed slower)", rows["check"], allowed, delays["check"]))
        print(
            summary("  + toppra torque constraint", rows["torque_timing"], allowed, delays["torque_timing"])
        )
        print("  median wall time [ms]: " + ", ".join(f"{k} {np.nanmedian(v):.2f}" for k, v in ms.items()))
        if args.closed_loop:
            profile = demonstrated_profile(robot, train)
            ratios: dict[str, list[float]] = {"free": [], "checked": []}
            cl_delay: list[float] = []
            check_ms: list[float] = []
            stage_free: list[float] = []
            stage_slow: list[float] = []
            for d in test:
                free = replay_demo(model, robot, d, profile, ClosedLoopSettings(), motion_checks)
                slow = replay_demo(
                    model,
                    robot,
                    d,
                    profile,
                    ClosedLoopSettings(),
                    CheckSuite([*motion_checks.checks, check]),
                    CheckContext(objects=objects),
                )
                truth = CheckContext(objects=objects, task=d.task)
                for key, res in (("free", free), ("checked", slow)):
                    ratios[key].append(peak(check, res.trajectory, truth))
                cl_delay.append(slow.arrival_s - free.arrival_s)
                for p in slow.plans:  # the check alone, on every committed re-plan's remaining motion
                    t0 = time.perf_counter()
                    check.check(p, truth)
                    check_ms.append((time.perf_counter() - t0) * 1e3)
                stage_free.extend(r.stage_ms.get("checks", np.nan) for r in free.replans)
                stage_slow.extend(r.stage_ms.get("checks", np.nan) for r in slow.replans)
            print("closed loop (demonstrated limits; whole commanded trajectory, true task's object):")
            print(summary("  without the check", ratios["free"], allowed))
            print(summary("  with the check on every re-plan", ratios["checked"], allowed, cl_delay))
            print(
                f"  the joint-torque check per committed re-plan: median {np.median(check_ms):.3f} ms, "
                f"95th percentile {np.percentile(check_ms, 95):.3f} ms ({len(check_ms)} re-plans)\n"
                f"  every check of a re-plan: median {np.nanmedian(stage_free):.3f} ms without it, "
                f"{np.nanmedian(stage_slow):.3f} ms with it"
            )


if __name__ == "__main__":
    main()
