"""Benchmark: the re-plan cycle of the closed loop, timed on exactly what ``ipromp-pin replay`` runs.

The command line is parsed by the ``replay`` command's own parser, and the set-up is the replay's
(:func:`ipromp_pin.app.replay.prepare_replay`: the pipeline's data and settings, the demo held
out, the model trained on every other demo with the robot's kinematics, or taken from the model
cache, the limit profile, the checks primed on the training motions). The held-out demo is then
replayed ``--replays`` times after one warm-up replay (:func:`~ipromp_pin.planning.closed_loop.replay_demo`,
the replay's closed loop: streaming update with every human sample, the re-plan's conditioning,
ruckig re-target and checks). A cycle is one re-plan as the replay report counts it
(``Re-plan cycle median`` of ``report.txt`` is the median over one replay's re-plans).

    taskset -c 0 python benchmarks/closed_loop.py [PIPELINE] [--dataset DATASET] [--observe GROUPS]
        [--replays 10] [--json FILE] [replay options...]

compares with ``taskset -c 0 ipromp-pin replay PIPELINE --dataset DATASET --observe GROUPS`` (one
replay in a fresh process: the figure to compare is this script's "first replay" line, the later
replays show the warm cycle). Unknown options are passed to ``replay`` (e.g. ``--limits``,
``--replan-rate``). The process is pinned to one CPU.

``--without CHECK[,CHECK...]`` (e.g. ``human_clearance,contact_speed``): every timed replay is
followed by the same replay with those timed-motion checks left out, and the medians of the two
cycles, their difference and ratio are printed: what the checks add to the re-plan cycle, measured
back to back.

``--smoke``: the pipeline's built-in synthetic demos with a small model (loaded as ``--model``, as
``replay --model`` does), one replay after the warm-up, compared without the two human checks:
seconds, what the test suite runs.

Prints the median and 95th percentile of the cycle and of each stage over every re-plan of the timed
replays, the median of each replay's own median, and how many motions the checks judged per re-plan
(a re-plan slowed for the checks judges its slower re-targets too).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ipromp_pin.app import build_parser
from ipromp_pin.app.arguments import closed_loop_settings, pipeline_config
from ipromp_pin.app.session import prepare_replay
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.safety import CheckSuite

SMOKE_MODEL = {"head": False, "handover": False, "coupling": "all", "n_basis": 15}
"""The small model of ``--smoke`` (fitted in seconds)."""


def smoke_model(folder: Path) -> Path:
    """A small model of the built-in synthetic demos, saved in ``folder``."""
    path = folder / "smoke.ipromp"
    ds = make_synthetic_dataset(n_tasks=3, n_demos=5, seed=0)
    IProMP(observe=["orientation", "emg"], **SMOKE_MODEL).fit(ds).save(path)
    return path


def replay_args(
    args: argparse.Namespace, rest: list[str], out: Path, model: Path | None
) -> argparse.Namespace:
    """The ``replay`` command's parsed arguments for this benchmark's options."""
    argv = ["replay", args.pipeline, "--out", str(out), "--no-preview", *rest]
    if args.dataset:
        argv += ["--dataset", str(args.dataset)]
    if args.observe:
        argv += ["--observe", args.observe]
    if model is not None:
        argv += ["--model", str(model)]
    return build_parser().parse_args(argv)


def count_rounds(suite: CheckSuite) -> list[int]:
    """A one-element counter of the motions ``suite`` checks (its ``run`` calls), from now on."""
    calls = [0]
    run = suite.run

    def counted(*args: Any, **kwargs: Any) -> list:
        calls[0] += 1
        return run(*args, **kwargs)

    suite.run = counted  # type: ignore[method-assign]
    return calls


def summary(cycles: list[list[float]], stages: dict[str, list[float]]) -> dict:
    c = np.concatenate(cycles)
    return {
        "n_replans": int(c.size),
        "cycle_ms": {"median": float(np.median(c)), "p95": float(np.percentile(c, 95))},
        "replay_median_ms": float(np.median([np.median(r) for r in cycles])),
        "stages_ms": {
            k: {"median": float(np.median(v)), "p95": float(np.percentile(v, 95))} for k, v in stages.items()
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "pipeline", nargs="?", default="baxter_handover", help="pipeline (default %(default)s)"
    )
    parser.add_argument("--dataset", type=Path, default=None, help="dataset (default: the pipeline's)")
    parser.add_argument("--observe", default=None, help="observed groups, as replay's --observe")
    parser.add_argument("--replays", type=int, default=10, help="timed replays after the warm-up")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--smoke", action="store_true", help="synthetic demos, a small model, 1 replay")
    parser.add_argument(
        "--without", default="", help="comma-separated checks to leave out in an interleaved second set"
    )
    args, rest = parser.parse_known_args()
    left_out = [c for c in args.without.split(",") if c]
    if args.smoke:
        args.dataset, args.observe, args.replays = None, None, 1
        left_out = left_out or ["human_clearance", "contact_speed"]  # the comparison runs too
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    with tempfile.TemporaryDirectory() as tmp:
        model = smoke_model(Path(tmp)) if args.smoke else None
        ns = replay_args(args, rest, Path(tmp) / "out", model)
        cfg = pipeline_config(ns)
        start = {"start_ratio": ns.start_ratio, "start_after_s": ns.start_after}
        settings = closed_loop_settings(ns, control_rate_hz=cfg.control_rate_hz, **start)
        setup = prepare_replay(cfg, settings, ns.limits)
        session = setup.session
        known = set(session.suite.names)
        unknown = sorted(set(left_out) - known)
        if unknown:
            raise SystemExit(f"--without: unknown checks {unknown} (the replay runs {sorted(known)})")
        fewer = replace(setup, session=replace(session, suite=session.suite.without(left_out)))
        rounds = count_rounds(session.suite)
        cycles: list[list[float]] = []
        cycles_without: list[list[float]] = []
        stages: dict[str, list[float]] = {}
        first: list[float] = []
        for i in range(args.replays + 1):
            result = setup.replay(settings)
            replans = [r.cycle_ms for r in result.replans]
            if i == 0:  # the replay of a fresh process: what `ipromp-pin replay` reports
                first = replans
                if left_out:
                    fewer.replay(settings)  # its warm-up
                rounds[0] = 0
                continue
            cycles.append(replans)
            for r in result.replans:
                for k, v in r.stage_ms.items():
                    stages.setdefault(k, []).append(v)
            if left_out:
                cycles_without.append([r.cycle_ms for r in fewer.replay(settings).replans])
    out = summary(cycles, stages)
    out["check_rounds_per_replan"] = rounds[0] / max(out["n_replans"], 1)
    if left_out:
        with_ms, without_ms = out["cycle_ms"]["median"], float(np.median(np.concatenate(cycles_without)))
        out["without"] = {"checks": left_out, "cycle_median_ms": without_ms, "added_ms": with_ms - without_ms}
    print(
        f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, one CPU"
    )
    print(
        f"data: {cfg.dataset or 'synthetic'}; demo {session.demo.task}/{session.demo.name}; trained on "
        f"{len(session.train)} demos; {args.replays} timed replays, {out['n_replans']} re-plans"
    )
    print(f"{'stage':<16}{'median [ms]':>12}{'p95 [ms]':>10}")
    for k, v in out["stages_ms"].items():
        print(f"{k:<16}{v['median']:>12.3f}{v['p95']:>10.3f}")
    print(f"{'cycle':<16}{out['cycle_ms']['median']:>12.3f}{out['cycle_ms']['p95']:>10.3f}")
    print(f"median of each replay's median: {out['replay_median_ms']:.2f} ms")
    print(f"check rounds per re-plan: {out['check_rounds_per_replan']:.2f}")
    print(
        f"first replay (warm-up; what `ipromp-pin replay` reports as Re-plan cycle median): "
        f"median {np.median(first):.2f} ms"
    )
    print(f"first re-plan of a replay: median {np.median([c[0] for c in cycles]):.2f} ms")
    if left_out:
        w = out["without"]
        ratio = out["cycle_ms"]["median"] / w["cycle_median_ms"]
        print(
            f"without {', '.join(left_out)} (interleaved replays): cycle median "
            f"{w['cycle_median_ms']:.2f} ms; the checks add {w['added_ms']:.2f} ms ({ratio:.2f}x)"
        )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        out["first_replay_median_ms"] = float(np.median(first))
        out["dataset"] = str(cfg.dataset or "synthetic")
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
