"""Benchmark: ``ipromp-pin plan`` on a batch of recordings (time per recording, and --jobs 2 vs 1).

Per shared dataset, the last ``--held-out`` recordings (the last of each task in turn, by stamp) are
planned with a model ``ipromp-pin train`` fitted on the others (default 50 + 50 = 100 recordings),
as a user plans new recordings: no preview, the trajectory files, the rosbag2 folder and the report
of each. Prints the time per recording with one worker (the gap between two recordings' completion:
reading, recognition, planning, checks, retreat, files), its median over the warm recordings (the
first ``--warm-up`` of each dataset apart: the kernels' first calls), and the wall time of the whole
batch with ``--jobs 1`` and ``--jobs 2`` (alternating, ``--repeats`` times each; median and ratio).

    taskset -c 0,1 python benchmarks/plan_batch.py [--datasets ../shared/datasets] [--held-out 50]

``--smoke``: 2 synthetic tasks, 4 training demos and 4 recordings: seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

from ipromp_pin.app import main as cli  # noqa: E402
from ipromp_pin.app.plan import run as plan_run  # noqa: E402
from ipromp_pin.data import ObservationWindow  # noqa: E402
from ipromp_pin.plans.batch import PlanOptions  # noqa: E402
from ipromp_pin.readers import expand_recordings  # noqa: E402

DATASETS = ("handover_20171128", "chen2017_handover")


def held_out(dataset: Path, n: int) -> tuple[list[Path], list[str]]:
    """The last ``n`` recordings of ``dataset`` (the last of each task in turn) and their
    ``train --holdout`` arguments (task/name)."""
    tasks = sorted(p for p in dataset.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))
    found = {t.name: expand_recordings([t]) for t in tasks}
    per_task = {t: math.ceil(n / len(tasks)) - (i >= n % len(tasks) > 0) for i, t in enumerate(found)}
    out: list[Path] = []
    holdout: list[str] = []
    for task, paths in found.items():
        last = sorted(paths, key=_stamp)[-per_task[task] :]
        out += last
        holdout += [f"{task}/{_stamp(p)}" for p in last]
    return out, holdout


def _task(path: Path, dataset: Path) -> str | None:
    """The task folder of a recording of ``dataset`` (None: not in it)."""
    try:
        return path.relative_to(dataset).parts[0]
    except ValueError:
        return None


def _stamp(path: Path) -> str:
    """A recording's name (its stamp): a multimodal recording's folder, a chen2017 prefix."""
    return path.parent.name if path.name == "multiModal_states.csv" else path.stem


def timed_batch(model: Path, recordings: list[Path], out: Path, jobs: int) -> tuple[float, list[float], list]:
    """Plan ``recordings``: (wall time [s], per-recording gaps [s] in completion order, rows)."""
    stamps: list[float] = []

    def log(line: str) -> None:
        if line.startswith("["):
            stamps.append(time.perf_counter())

    t0 = time.perf_counter()
    outcome = plan_run(model, [str(p) for p in recordings], out, PlanOptions(window=ObservationWindow()),
                       jobs=jobs, log=log)  # fmt: skip
    wall = time.perf_counter() - t0
    done = stamps[1:-1]  # the "[plan]" start line and the final line apart
    gaps = list(np.diff([stamps[0], *done]))
    return wall, gaps, outcome.rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--datasets", type=Path, default=ROOT.parent / "shared" / "datasets")
    ap.add_argument("--held-out", type=int, default=50, help="recordings planned per dataset")
    ap.add_argument("--warm-up", type=int, default=3, help="first recordings of each dataset not counted")
    ap.add_argument("--repeats", type=int, default=2, help="batches per --jobs setting")
    ap.add_argument("--smoke", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        batches: list[tuple[str, Path, list[Path]]] = []
        if args.smoke:
            assert cli(["synth", str(tmp / "train"), "--tasks", "2", "--demos", "4"]) == 0
            assert cli(["synth", str(tmp / "new"), "--tasks", "2", "--demos", "2", "--seed", "9"]) == 0
            assert cli(["train", str(tmp / "train"), "--out", str(tmp / "m.npz")]) == 0
            batches.append(("synthetic", tmp / "m.npz", expand_recordings([tmp / "new"])))
            args.warm_up, args.repeats = 1, 1
        else:
            for name in DATASETS:
                recordings, holdout = held_out(args.datasets / name, args.held_out)
                model = tmp / f"{name}.npz"
                flags = [a for h in holdout for a in ("--holdout", h)]
                assert cli(["train", str(args.datasets / name), "--out", str(model), *flags]) == 0
                batches.append((name, model, recordings))
        counts = ", ".join(f"{n} {len(r)}" for n, _, r in batches)
        print(f"{sum(len(b[2]) for b in batches)} recordings: {counts}")
        warm: list[float] = []
        for name, model, recordings in batches:
            wall, gaps, rows = timed_batch(model, recordings, tmp / "out" / name, jobs=1)
            warm += gaps[args.warm_up :]
            statuses = {s: sum(r.status == s for r in rows) for s in ("passed", "failed", "unreadable")}
            right = sum(r.task == _task(Path(r.recording), args.datasets / name) for r in rows)
            print(f"{name}: {len(rows)} planned in {wall:.1f} s (first {gaps[0]:.2f} s), {statuses}; "
                  f"task recognised {right}/{len(rows)}")  # fmt: skip
        print(
            f"per recording (--jobs 1, warm, no preview): median {np.median(warm):.3f} s, "
            f"p90 {np.percentile(warm, 90):.3f} s over {len(warm)}"
        )
        walls: dict[int, list[float]] = {1: [], 2: []}
        everything = [(m, r) for _, m, r in batches]
        for _ in range(args.repeats):
            for jobs in (1, 2):
                total = 0.0
                for i, (model, recordings) in enumerate(everything):
                    wall, _, _ = timed_batch(model, recordings, tmp / f"jobs{jobs}" / str(i), jobs=jobs)
                    total += wall
                walls[jobs].append(total)
        one, two = float(np.median(walls[1])), float(np.median(walls[2]))
        print(f"batch wall time: --jobs 1 {one:.1f} s, --jobs 2 {two:.1f} s: {one / two:.2f}x faster")


if __name__ == "__main__":
    main()
