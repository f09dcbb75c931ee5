"""Every benchmark script still runs: its ``--smoke`` setting (tiny synthetic data, a few calls, no
shared datasets, no clone) as a subprocess, one test per script (the test workers share them out),
each exiting 0 and printing its result lines. A benchmark added without an entry here fails the
test."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"

HELPERS = {"checkouts.py"}
"""Modules of ``benchmarks/`` that are imported by the scripts, not run."""

EXPECTED = {
    "arm_evaluation.py": [
        r"\| panda \| \d+ \| \d+/\d+ \([\d.]+ %\) \| [\d.]+ / [\d.]+ \| [\d.]+ \([-+][\d.]+\)",
        r"smoke: 2 arms, one-shot and closed loop",
    ],
    "add_task.py": [r"(?m)^N=3: accuracy of the refit minus the addition: median [-+][\d.]+", r"of a refit"],
    "ab_compare.py": [
        r"full update, 10% observed: [\d.]+ -> [\d.]+",
        r"streaming update: [\d.]+ -> [\d.]+",
        r"training per task: [\d.]+ -> [\d.]+ ms",
    ],
    "baxter_springs.py": [r"s1 spring torque = -(39|40)\.\d\d \+ -2[45]\.\d\d \* q_s1"],
    "torques.py": [
        r"before \(no torque check\)\s+\d+/\d+\s+over",
        r"joint-torque check per committed re-plan",
    ],
    "closed_loop.py": [
        r"(?m)^cycle\s+[\d.]+\s+[\d.]+",
        r"first re-plan of a replay: median [\d.]+ ms",
        r"without human_clearance, contact_speed \(interleaved replays\): cycle median [\d.]+ ms",
    ],
    "closed_loop_cv.py": [r"\| err \[cm\] \|", r"(?m)^0\.2 \| 20 \| 0\.9 \| 90 \| 0\.2 \| [\d.]+ \|"],
    "human_checks.py": [r"failing the human checks \(after re-timing\): \d+/\d+", r"cost of both checks"],
    "first_minute.py": [r"(?m)^cold\s+median\s+[\d.]+ s wall"],
    "handover_geometry.py": [
        r"synthetic \(seed 0, assumed human\): \d+ demos",
        r"gripper - torso\s+x [-+][\d.]+",
        r"demo's robot path\s+timed like a plan: slow-down median [\d.]+ \[95th [\d.]+\]",
        r"straight joint line between its ends\s+timed like a plan: slow-down median [\d.]+",
        r"on ur5: synthetic \(seed 0, assumed human\): \d+ demos; robot path at the demo's own pace",
        r"largest at the demo's own pace between: \w+ -> \w+ \d+",
    ],
    "gripper_demos.py": [
        r"ratio gripper/joints [\d.]+",
        r"gripper vs joint model: median [\d.]+ cm",
        r"passed: joint model \d+/3, gripper model \d+/3",
    ],
    "inference.py": [r"(?m)^paper\s+\d+\s+12\s", r"speed-up \d+x", r"task accuracy [\d.]+"],
    "model_load.py": [r"this checkout:\s+[\d.]+ ms", r"paired difference \(this - other\): median"],
    "placement.py": [
        r"panda study grid \(yaw 0\): best \([-\d., ]+\) m: \d+/\d+ \([\d.]+%\) reached",
        r"panda settings \([-\d., ]+\) on synthetic: \d+/\d+ \([\d.]+%\) reached",
        r"panda: retarget a whole path \(\d+ samples\): median [\d.]+ ms",
    ],
    "pipeline.py": [r"total \(observation->files\)\s+[\d.]+"],
    "plan_batch.py": [
        r"per recording \(--jobs 1, warm, no preview\): median [\d.]+ s",
        r"batch wall time: --jobs 1 [\d.]+ s, --jobs 2 [\d.]+ s: [\d.]+x faster",
    ],
    "retarget.py": [
        r"panda one-shot retarget: Pinocchio median [\d.]+ ms, compiled median [\d.]+ ms",
        r"panda re-plan retarget: Pinocchio median [\d.]+ ms, compiled median [\d.]+ ms",
        r"largest joint difference [\d.]+e[-+]\d+ rad",
    ],
    "read_formats.py": [r"rosbag2 \(MCAP\)\s+[\d.]+ ms", r"rosbag2 \(SQLite\)\s+[\d.]+ ms"],
    "profile_update.py": [r"(?m)^  total\s+[\d.]+", r"stream_group \(per update\)\s+[\d.]+"],
    "speed_margin_cv.py": [r"(?m)^0\.1 \| 8 \| 0 \| 0 \| [\d.]+ \|", r"chosen: speed_margin = 0"],
    "settings_cv.py": [r"(?m)^log_groups= pooling=0\.0\s+0\.2\s+[\d.]+"],
    "kernel_gains.py": [
        r"(?m)^  part_stats\s+\d+\s+[\d.]+ ->\s+[\d.]+",
        r"full update, 20 % observed",
    ],
    "sklearn_models.py": [
        r"logistic regression \(head\): \d+ fits, [\d.]+ -> [\d.]+ s",
        r"k nearest neighbours \(hand-over\): \d+ fits, [\d.]+ -> [\d.]+ s",
    ],
}
"""Benchmark -> patterns its smoke run must print (its result lines)."""


def _run(name: str) -> tuple[str, subprocess.CompletedProcess]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / name), "--smoke"],
        cwd=BENCHMARKS,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    return name, done


def test_every_benchmark_has_a_smoke_entry():
    scripts = sorted(p.name for p in BENCHMARKS.glob("*.py") if p.name not in HELPERS)
    assert scripts == sorted(EXPECTED), "every benchmark needs a --smoke entry in EXPECTED"


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_the_benchmark_runs_its_smoke_setting(name):
    _, done = _run(name)
    tail = f"{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    assert done.returncode == 0, f"{name}: exit {done.returncode}\n{tail}"
    missing = [p for p in EXPECTED[name] if not re.search(p, done.stdout)]
    assert not missing, f"{name}: printed no line matching {missing}:\n{done.stdout[-2000:]}"
