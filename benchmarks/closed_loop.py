"""Benchmark: one re-plan cycle of the closed loop, on one core, in the paper's setting.

Paper setting: 3 tasks, orientation + EMG observed, Baxter's 7 left-arm joints, the robot starting
after 20 % of the human's motion. The model is trained on the first ``--n-train`` demos of every
task (``chen2017_handover`` when given, else the built-in synthetic demos), the collision certifier
is primed on their robot motions (offline, like ``ipromp-pin replay``), and the other demos are
replayed in the closed loop (demonstrated limits, default settings). A cycle is what a re-plan
costs online: the streaming update with the latest human sample, conditioning the robot
trajectory, the ruckig re-target of the remaining motion and its checks (limits, joint limits,
workspace, certified self-collision). The process is pinned to one CPU and BLAS to one thread.

    python benchmarks/closed_loop.py [--dataset DATASET] [--n-train 15] [--replays 20] [--json FILE]

``--smoke``: 2 synthetic tasks, 4 training demos each, one replay (after the warm-up): seconds, what
the test suite runs.

Prints the median and 95th percentile of the cycle and of each stage, over every re-plan of every
replay after the first replay (warm-up).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin.handover.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot, load_robot_settings
from ipromp_pin.robot.clearance import ClearanceCertifier


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--dataset", type=Path, default=None, help="real dataset (default: synthetic)")
    parser.add_argument("--n-train", type=int, default=15)
    parser.add_argument("--replays", type=int, default=20)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--smoke", action="store_true", help="2 synthetic tasks, 4 demos, 1 replay: seconds")
    args = parser.parse_args()
    if args.smoke:
        args.dataset, args.n_train, args.replays = None, 4, 1

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    observe = ["orientation", "emg"]
    if args.dataset is None:
        n_tasks, n_test = (2, 1) if args.smoke else (3, 8)
        ds = make_synthetic_dataset(n_tasks=n_tasks, n_demos=args.n_train + n_test, seed=0)
    else:
        ds = load_dataset(args.dataset, robot_joints=load_robot_settings("baxter_left").recorded_arm_joints)
    train = [d for demos in ds.demos.values() for d in demos[: args.n_train]]
    test = [d for demos in ds.demos.values() for d in demos[args.n_train :]]
    test = [test[i] for i in np.linspace(0, len(test) - 1, min(args.replays, len(test))).round().astype(int)]
    robot = load_robot("baxter_left")
    with threadpool_limits(limits=1):
        smoke_model = {"head": False, "handover": False, "coupling": "all"} if args.smoke else {}
        model = IProMP(observe=observe, **smoke_model).fit(train)
        profile = demonstrated_profile(robot, train)
        certifier = ClearanceCertifier(robot)
        t0 = time.perf_counter()
        for d in train:
            certifier.certify(d.groups["robot"])
        prime_s = time.perf_counter() - t0
        cycles: list[float] = []
        stages: dict[str, list[float]] = {}
        first: list[float] = []
        for i, d in enumerate([test[0], *test]):
            result = replay_demo(model, robot, d, profile, ClosedLoopSettings(), certifier)
            if i == 0:
                continue  # warm-up (compiles and loads the kernels)
            first.append(result.replans[0].cycle_ms)
            for r in result.replans:
                cycles.append(r.cycle_ms)
                for k, v in r.stage_ms.items():
                    stages.setdefault(k, []).append(v)
    c = np.array(cycles)
    print(
        f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        "one CPU, BLAS 1 thread"
    )
    print(
        f"data: {args.dataset or 'synthetic'}; trained on {len(train)} demos; {len(test)} replays, {c.size} "
        f"re-plans; certifier primed in {prime_s:.1f} s"
    )
    print(f"{'stage':<16}{'median [ms]':>12}{'p95 [ms]':>10}")
    for k, v in stages.items():
        print(f"{k:<16}{np.median(v):>12.3f}{np.percentile(v, 95):>10.3f}")
    print(f"{'cycle':<16}{np.median(c):>12.3f}{np.percentile(c, 95):>10.3f}   (target: median <= 2 ms)")
    print(f"first re-plan of a replay: median {np.median(first):.2f} ms, max {np.max(first):.2f} ms")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {
                    "dataset": str(args.dataset or "synthetic"),
                    "n_replans": int(c.size),
                    "cycle_ms": {"median": float(np.median(c)), "p95": float(np.percentile(c, 95))},
                    "stages_ms": {
                        k: {"median": float(np.median(v)), "p95": float(np.percentile(v, 95))}
                        for k, v in stages.items()
                    },
                    "first_replan_ms": {"median": float(np.median(first)), "max": float(np.max(first))},
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
