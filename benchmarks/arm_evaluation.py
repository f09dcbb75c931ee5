"""Issue 37's evaluation per arm: a Baxter model executed on a Panda, a UR5, an xArm 7 and a Kinova Jaco 2
(retargeted through the gripper), against Baxter's own, on both shared datasets.

For every arm and dataset, ``ipromp-pin evaluate --robot ARM``
(:func:`ipromp_pin.evaluation.run.run_evaluate`) with the ``folds`` protocol: per task the demos in 5
seeded random folds, each fold tested once by a model of 20 demos of the other folds, so that every
demo is a test demo once; the first 20 % of each test demo observed (``chen2017_handover``:
orientation + EMG; ``handover_20171128``: the tracked left hand + EMG). Baxter runs with
``--arm-scores`` (its own model, the same plans and re-evaluation).

* **one-shot**: every test demo's plan as ``run`` makes it (retargeted, timed, checked, re-timed);
* **closed loop** (``--closed-loop-folds N``: the first N folds, it is heavier): every test demo replayed.

Printed per dataset and arm: the hand-over poses reached by the inverse kinematics (of the
retargeted plans or re-plans) and the largest residuals where reached; the median over the demos of
the hand-over error (the arm's gripper vs the recorded Baxter gripper at the demo's end, scene frame)
and of the arrival delay, each with its difference to Baxter's; the plans that passed, refused by
check (the closed loop: the replays that moved, a re-plan committed toward the hand-over, and the
refused re-plans by check); and the plans that passed (the replays) with a violation found by the independent
re-evaluation of the trajectory (:mod:`ipromp_pin.evaluation.independent`: the arm's URDF limits,
torques with the true task's object over 90 %, self-collision; the human judged against the whole
recording). Each run's JSON is kept in ``--out`` and reused when it is there (delete it to re-run).

    PYTHONPATH=. nice python benchmarks/arm_evaluation.py ../shared/datasets/chen2017_handover \
        ../shared/datasets/handover_20171128 --out out/arm_eval [--closed-loop-folds 1]

``--smoke``: the built-in synthetic demos (2 tasks x 6), Baxter and the Panda, one fold of three,
one-shot and closed loop (a minute).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from ipromp_pin.evaluation.arm_plans import violations_of
from ipromp_pin.evaluation.run import EvaluateRequest, run_evaluate
from ipromp_pin.evaluation.windows import Window
from ipromp_pin.readers.native import write_demo
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot_settings

ARMS = ("baxter_left", "panda", "ur5", "xarm7", "kinova_jaco2")
OBSERVE = {"chen2017_handover": "orientation,emg", "handover_20171128": "/left_hand_1,emg"}
"""The observed groups per dataset (others: orientation + EMG)."""


def run_one(dataset: Path, arm: str, closed: bool, out: Path, args: argparse.Namespace) -> dict:
    """The JSON of one arm on one dataset: the one-shot run of its folds, or the closed-loop runs, one
    per fold (``closed_<dataset>_<arm>_f<k>.json``), their cells together (each run unless its JSON
    is in ``out`` already)."""
    if not closed:
        return run_folds(
            dataset,
            arm,
            False,
            list(range(args.oneshot_folds)),
            out / f"oneshot_{dataset.name}_{arm}.json",
            args,
        )
    docs = [
        run_folds(dataset, arm, True, [k], out / f"closed_{dataset.name}_{arm}_f{k + 1}.json", args)
        for k in range(args.closed_loop_folds)
    ]
    return docs[0] | {"cells": [c for d in docs for c in d["cells"]]}


def run_folds(
    dataset: Path, arm: str, closed: bool, folds: list[int], path: Path, args: argparse.Namespace
) -> dict:
    """The JSON of one evaluation of ``folds`` (0-based), run unless ``path`` exists."""
    if path.exists():
        return json.loads(path.read_text())
    mode = "closed" if closed else "oneshot"
    request = EvaluateRequest(
        dataset=dataset,
        observe=[OBSERVE.get(dataset.name, "orientation,emg").split(",")],
        grid=[(args.n_train, Window("ratio", args.ratio))],
        protocols=["folds"],
        n_folds=args.folds,
        run_folds=folds,
        robot=arm,
        arm_scores=True,
        closed_loop=closed,
        json=path,
        command=f"benchmarks/arm_evaluation.py ({mode}, {arm}, folds {[k + 1 for k in folds]})",
        log=lambda _line: None,
    )
    t0 = time.perf_counter()
    run_evaluate(request)
    print(f"  ran {path.name}: {time.perf_counter() - t0:.0f} s", flush=True)
    return json.loads(path.read_text())


def found(judged: dict | None, arm: str) -> list[str]:
    """What the re-evaluation ``judged`` found violated (recomputed from its measures by
    :func:`~ipromp_pin.evaluation.arm_plans.violations_of`: the same rule for every run's JSON)."""
    if judged is None:
        return []
    return violations_of(judged, load_robot_settings(arm).human.min_separation_m)


def contacts_of(violated: list[dict]) -> dict[str, int]:
    """Where the recorded human touched the arm in plans (or replays) whose re-evaluation found a
    ``human_contact``: ``"link - body part"`` -> how many (its ``judged.human_closest``; none in runs
    written before it was recorded)."""
    out: Counter[str] = Counter()
    for v in violated:
        closest = (v["judged"] or {}).get("human_closest")
        if "human_contact" in v["violations"] and closest:
            out[f"{closest[0]} - {closest[1]}"] += 1
    return dict(sorted(out.items()))


def one_shot_rows(doc: dict) -> dict:
    """Per-demo plans of a one-shot run -> the arm's figures."""
    arm = doc["meta"]["robot"]
    plans = [t["plan"] for c in doc["cells"] for t in c["trials"] if t.get("plan") is not None]
    for p in plans:
        p["violations"] = found(p["judged"], arm)
    moved = [p for p in plans if p["retargeted"]]
    reached = [p for p in moved if p["reached"]]
    passed = [p for p in plans if p["passed"]]
    refused = Counter(f for p in plans if not p["passed"] for f in p["failures"])
    violated = [p for p in passed if p["violations"]]
    kinds = Counter(v for p in violated for v in p["violations"])
    return {
        "contacts": contacts_of(violated),
        "n": len(plans),
        "retargeted": len(moved),
        "reached": len(reached),
        "ik_mm": max((p["ik_residual_mm"] for p in reached), default=None),
        "ik_deg": max((p["ik_residual_deg"] for p in reached), default=None),
        "error_cm": _median([p["handover_error_cm"] for p in passed]),
        "delay_s": _median([p["arrival_delay_s"] for p in passed]),
        "passed": len(passed),
        "refused": dict(sorted(refused.items())),
        "violated": len(violated),
        "found": dict(sorted(kinds.items())),
        "torque": max((p["judged"]["torque_ratio"] for p in plans if p["judged"]), default=None),
    }


def closed_rows(doc: dict) -> dict:
    """Per-demo replays of a closed-loop run -> the arm's figures."""
    trials = [t for c in doc["cells"] for t in c["closed_loop_trials"]]
    done = [t for t in trials if t.get("arm") is not None]
    arms = [t["arm"] for t in done]
    for a in arms:
        a["violations"] = found(a["judged"], doc["meta"]["robot"])
    refused: Counter[str] = Counter()
    for a in arms:
        refused.update(a["refused"])
    violated = [a for a in arms if a["violations"]]
    kinds = Counter(v for a in violated for v in a["violations"])
    return {
        "contacts": contacts_of(violated),
        "n": len(trials),
        "retargeted": sum(a["retargeted"] for a in arms),
        "reached": sum(a["reached"] for a in arms),
        "ik_mm": max(
            (a["max_ik_residual_mm"] for a in arms if a["max_ik_residual_mm"] is not None), default=None
        ),
        "ik_deg": max(
            (a["max_ik_residual_deg"] for a in arms if a["max_ik_residual_deg"] is not None), default=None
        ),
        "error_cm": _median([t["closed_loop_handover_error_cm"] for t in done]),
        "final_cm": _median([t["closed_loop_final_error_cm"] for t in done]),
        "delay_s": _median([t["closed_loop_arrival_delay_s"] for t in done]),
        "passed": sum(bool(t.get("closed_loop_final_task")) for t in done),
        "refused": dict(sorted(refused.items())),
        "violated": len(violated),
        "found": dict(sorted(kinds.items())),
        "torque": max((a["judged"]["torque_ratio"] for a in arms if a["judged"]), default=None),
    }


def _median(values: list) -> float | None:
    finite = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.median(finite)) if finite else None


def _num(x: float | None, digits: int = 2, sign: bool = False) -> str:
    return "-" if x is None else (f"{x:+.{digits}f}" if sign else f"{x:.{digits}f}")


def print_table(title: str, rows: dict[str, dict], closed: bool) -> None:
    """One Markdown table: a row per arm, the differences to Baxter's (the first row)."""
    base = rows.get("baxter_left")
    unit = "replays" if closed else "plans"
    print(f"\n{title}\n")
    if closed:
        print(
            "(replays: passed = moved toward the hand-over, a re-plan committed; refused = re-plans; "
            "errors and delays: medians over every replay; the hand-over error at the recorded hand-over "
            "time, and where the arm comes to rest)\n"
        )
    else:
        print("(refused = plans; errors and delays: medians over the passed plans)\n")
    print(
        f"| arm | {unit} | IK reached | largest IK residual [mm / deg] | hand-over error [cm] (vs Baxter) "
        "| arrival delay [s] (vs Baxter) | passed | refused (by check) | passed with a violation "
        "| peak torque |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for arm, r in rows.items():
        reach = (
            f"{r['reached']}/{r['retargeted']} ({100 * r['reached'] / r['retargeted']:.1f} %)"
            if r["retargeted"]
            else "-"
        )
        d_err = d_delay = None
        if base is not None and arm != "baxter_left":
            if r["error_cm"] is not None and base["error_cm"] is not None:
                d_err = r["error_cm"] - base["error_cm"]
            if r["delay_s"] is not None and base["delay_s"] is not None:
                d_delay = r["delay_s"] - base["delay_s"]
        refused = ", ".join(f"{k} {v}" for k, v in r["refused"].items()) or "none"
        found = ", ".join(f"{k} {v}" for k, v in r["found"].items())
        final = f"; at rest {_num(r['final_cm'])}" if "final_cm" in r else ""
        print(
            f"| {arm} | {r['n']} | {reach} | {_num(r['ik_mm'], 3)} / {_num(r['ik_deg'], 3)} "
            f"| {_num(r['error_cm'])} ({_num(d_err, sign=True)}){final} | {_num(r['delay_s'])} "
            f"({_num(d_delay, sign=True)}) | {r['passed']} | {refused} | {r['violated']}"
            f"{f' ({found})' if found else ''} | {_num(r['torque'], 3)} |"
        )
    touched = [
        f"{arm}: " + ", ".join(f"{k} {v}" for k, v in r["contacts"].items())
        for arm, r in rows.items()
        if r["contacts"]
    ]
    if touched:
        print(
            "\nwhere the recorded human touched passed "
            + unit
            + " (arm link - body part): "
            + "; ".join(touched)
        )


def smoke_dataset(folder: Path) -> Path:
    """The built-in synthetic demos (2 tasks x 6) written to ``folder``."""
    for task, demos in make_synthetic_dataset(n_tasks=2, n_demos=6, seed=1).demos.items():
        for d in demos:
            write_demo(d, folder / task / f"{d.name}.npz")
    return folder


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("datasets", type=Path, nargs="*", help="dataset folders (not with --smoke)")
    parser.add_argument("--out", type=Path, default=Path("out/arm_eval"), help="folder of the runs' JSON")
    parser.add_argument("--arms", nargs="+", default=list(ARMS))
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--closed-loop-folds", type=int, default=0, help="closed loop on the first N folds")
    parser.add_argument("--oneshot-folds", type=int, help="one-shot on the first N folds (default: all)")
    parser.add_argument("--n-train", type=int, default=20)
    parser.add_argument("--ratio", type=float, default=0.2)
    parser.add_argument("--smoke", action="store_true", help="synthetic demos, Baxter and the Panda, 1 fold")
    args = parser.parse_args()
    if not args.datasets and not args.smoke:
        parser.error("give the datasets (or --smoke)")
    tmp = None
    if args.smoke:
        tmp = tempfile.TemporaryDirectory()
        args.datasets = [smoke_dataset(Path(tmp.name) / "synthetic")]
        args.out, args.arms, args.n_train = Path(tmp.name) / "out", ["baxter_left", "panda"], 3
        args.folds, args.closed_loop_folds, args.oneshot_folds = 3, 1, 1
    args.oneshot_folds = args.oneshot_folds or args.folds
    args.out.mkdir(parents=True, exist_ok=True)
    for closed in (False, True):
        if closed and args.closed_loop_folds < 1:
            continue
        for dataset in args.datasets:
            rows = {}
            for arm in args.arms:
                doc = run_one(dataset, arm, closed, args.out, args)
                rows[arm] = closed_rows(doc) if closed else one_shot_rows(doc)
            what = f"closed loop, folds 1-{args.closed_loop_folds} of {args.folds}" if closed else "one-shot"
            print_table(
                f"{dataset.name}, {what}, n_train {args.n_train}, {args.ratio:.0%} observed", rows, closed
            )
    if args.smoke:
        print(f"\nsmoke: {len(args.arms)} arms, one-shot and closed loop")
    return 0


if __name__ == "__main__":
    sys.exit(main())
