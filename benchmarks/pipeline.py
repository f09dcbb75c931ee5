"""Benchmark: from a partial observation to written, checked, smoothed trajectory files.

Paper setting: 3 tasks, orientation + EMG observed, 7 Baxter joints, 20 % of the
motion observed. Model training and process start are excluded; everything
after the observation is timed: recognition + prediction, feasibility checks,
toppra + ruckig, writing ``trajectory.csv``, ``trajectory.json``, ``report.json``,
``report.txt`` and the rosbag2 folder ``rosbag/`` (as ``ipromp-pin run`` does). BLAS is pinned to
one thread (one core).

    python benchmarks/pipeline.py [--repeats 50] [--dataset DATASET] [--json FILE] [--no-rosbag]

Prints the median total and each stage's median and share. ``--smoke``: a model trained on 4
synthetic demos per task, 2 timed runs: seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin import atomic
from ipromp_pin.app.config import PipelineConfig
from ipromp_pin.app.session import choose_demo, get_model, load_data
from ipromp_pin.outputs.report import report_dict, report_text
from ipromp_pin.outputs.staging import OutputOptions, stage_plan, stage_report
from ipromp_pin.planning.one_shot import plan
from ipromp_pin.robot import load_robot
from ipromp_pin.safety import CheckSuite


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--dataset", type=Path, default=None, help="real dataset (default: synthetic)")
    parser.add_argument("--ratio", type=float, default=0.2)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--no-rosbag", action="store_true", help="do not write the rosbag2 folder")
    parser.add_argument("--smoke", action="store_true", help="train on 4 synthetic demos per task, 2 runs")
    args = parser.parse_args()
    if args.smoke:
        args.dataset, args.repeats = None, 2

    cfg = PipelineConfig(dataset=args.dataset, ratio=args.ratio, preview_html=False).validate()
    quiet = lambda _msg: None  # noqa: E731
    ds = load_data(cfg, quiet)
    if args.smoke:  # a small model (trained, not cached: the cache is keyed by the demos)
        ds = type(ds)(ds.root, {task: demos[-5:] for task, demos in ds.demos.items()})
    robot = load_robot(cfg.robot)
    demos = [d for task in ds.tasks for d in ds.demos[task][-3:]]
    cfg.demo = -1
    model = get_model(cfg, ds, choose_demo(ds, cfg), quiet)
    observations = [d.head(cfg.ratio, groups=cfg.observe) for d in demos]
    suite = CheckSuite.build(robot)  # every check, as ``run`` builds them (the assumed human)

    stages: dict[str, list[float]] = {}
    totals = []
    with threadpool_limits(limits=1), tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats + 3):
            obs = observations[i % len(observations)]
            t0 = time.perf_counter()
            result = plan(model, robot, obs, suite, control_rate_hz=cfg.control_rate_hz)
            t1 = time.perf_counter()
            with atomic.OutputSet(tmp) as out:  # the files as ``ipromp-pin run`` stages them
                stage_plan(result, out, obs, OutputOptions(rosbag=not args.no_rosbag))
                stage_report(out, report_dict(result, obs), report_text(result, obs))
                out.commit()
            t2 = time.perf_counter()
            if i < 3:  # warm-up
                continue
            totals.append((t2 - t0) * 1e3)
            for k, v in result.stage_ms.items():
                stages.setdefault(k, []).append(v)
            stages.setdefault("write_files", []).append((t2 - t1) * 1e3)

    total = statistics.median(totals)
    print(
        f"machine: {platform.processor() or platform.machine()}, {platform.python_version()}, BLAS 1 thread"
    )
    print(f"data: {args.dataset or 'synthetic'}, ratio {args.ratio}, {args.repeats} runs")
    print(f"{'stage':<28}{'median [ms]':>12}{'share':>8}")
    medians = {k: statistics.median(v) for k, v in stages.items()}
    for k, v in medians.items():
        print(f"{k:<28}{v:>12.2f}{v / total:>8.0%}")
    print(f"{'total (observation->files)':<28}{total:>12.2f}{1:>8.0%}")
    print(f"p90 total: {np.percentile(totals, 90):.2f} ms; target < 100 ms median")
    if args.json:
        args.json.write_text(
            json.dumps({"total_ms": total, "stages_ms": medians, "repeats": args.repeats}, indent=1)
        )


if __name__ == "__main__":
    main()
