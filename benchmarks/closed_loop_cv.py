"""Choose the closed loop's settings by cross-validation on training demos only.

Pool: the first ``--n-train`` demos of every task (the authors' order on ``chen2017_handover``, the
recorded order otherwise): training demos in every cell of the paper's protocol with at least that
many training demos. k-fold cross-validation over the pool: each fold trains the model (and derives
the demonstrated limit profile) on the other folds and replays its held-out demos in the closed loop
(``ipromp_pin.planning.closed_loop.replay_demo``) at start ratios 0.1 and 0.2 (the evaluation's ratios) for
every candidate setting.

    python benchmarks/closed_loop_cv.py DATASET --observe GROUPS [--n-train 10] [--folds 5] [--jobs 2]
        [--study settings|start|noise|estimates] [--json FILE]

``--study settings`` crosses blend horizon x re-plan rate x freeze phase x demonstrated-limit
percentile; ``--study start`` compares start ratios 0.1, 0.2, 0.3 at the chosen settings;
``--study noise`` compares the noise ratio with which the closed loop conditions the robot
trajectory (``condition_noise``: the model's own, chosen for recognition inside ``fit``, against
fixed values; ``--noise model,0.3,1`` restricts the candidates) at the chosen settings;
``--study estimates`` compares re-plans with and without the model's hand-over estimates
(``handover_estimates``: the hand-over regression and orientation estimate that the one-shot
prediction applies) at the chosen settings. The settings and start studies condition with the model's
own noise ratio (they were run before the noise study). Each fold's model is fitted with the robot's
kinematics, as the evaluation fits it (so with the hand-over regression and orientation estimate its
cross-validation keeps; the re-plans apply them where ``handover_estimates`` is true).
Prints, per candidate, the median (over held-out replays) closed-loop hand-over error [cm], final error [cm],
arrival delay [s], the largest limit ratio and the refused re-plans. The rule (fixed before running
it): the lowest hand-over error (mean of the datasets' medians) among the candidates whose median
arrival delay is at most 0.2 s on every dataset.

``--smoke`` (no dataset): the start study's one candidate at ratio 0.2, 2 folds over 4 synthetic
demos per task: seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from ipromp_pin.data import parse_groups, skeleton_frames
from ipromp_pin.evaluation.scoring import score_closed_loop
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import DemoLimitRecipe, gripper_kinematics, load_robot, load_robot_settings
from ipromp_pin.safety import CheckSuite

_STATE: dict = {}


def _fold(args: tuple) -> list[dict]:
    fold, train, test, candidates, ratios, observe, model_settings = args
    robot = load_robot("baxter_left")
    motion_checks = ["speed_limits", "joint_limits", "workspace", "self_collision"]  # the motion's own
    cert = _STATE.setdefault("cert", CheckSuite.build(robot, motion_checks))
    fk, fk_rot = gripper_kinematics(robot)  # as the evaluation fits it: the hand-over estimates on
    model = IProMP(observe=observe, **model_settings).fit(train, fk=fk, fk_rot=fk_rot)
    profiles = {}
    rows = []
    for cand in candidates:
        pct = cand["percentile"]
        if pct not in profiles:
            profiles[pct] = demonstrated_profile(robot, train, DemoLimitRecipe(percentile=pct))
        for ratio in ratios:
            settings = ClosedLoopSettings(
                start_ratio=ratio,
                replan_rate_hz=cand["replan_rate_hz"],
                blend_s=cand["blend_s"],
                freeze_phase=cand["freeze_phase"],
                condition_noise=cand.get("condition_noise"),
                handover_estimates=cand.get("handover_estimates", False),
            )
            for d in test:
                res = replay_demo(model, robot, d, profiles[pct], settings, cert)
                s = score_closed_loop(res, d, robot, check_collisions=False)
                rows.append(
                    {
                        **cand,
                        "ratio": ratio,
                        "fold": fold,
                        "demo": d.name,
                        "err": s.handover_error_cm,
                        "final": s.final_error_cm,
                        "delay": s.arrival_delay_s,
                        "ratio_max": s.max_limit_ratio,
                        "refused": s.refused_replans,
                    }
                )
    return rows


def _noises(text: str) -> list[float | None]:
    """The ``--noise`` candidates: comma-separated positive numbers or 'model'."""
    out: list[float | None] = []
    for v in text.split(","):
        if v.strip() == "model":
            out.append(None)
            continue
        try:
            nu = float(v)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{v}' is neither a number nor 'model'") from None
        if not (np.isfinite(nu) and nu > 0):
            raise argparse.ArgumentTypeError(f"'{v}' is not a positive number")
        out.append(nu)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path, nargs="?", help="dataset folder (not with --smoke)")
    parser.add_argument("--observe", default="orientation,emg")
    parser.add_argument("--n-train", type=int, default=10)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--study", choices=["settings", "start", "noise", "estimates"], default="settings")
    parser.add_argument("--blend", type=float, default=0.2, help="blend horizon of --study start [s]")
    parser.add_argument("--replan", type=float, default=20.0, help="re-plan rate of --study start [Hz]")
    parser.add_argument("--freeze", type=float, default=0.9, help="freeze phase of --study start|noise")
    parser.add_argument("--percentile", type=float, default=90.0, help="limit percentile of --study start")
    parser.add_argument(
        "--noise",
        dest="noises",
        type=_noises,
        default=[None, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0],
        help="candidates of --study noise, comma-separated ('model': the model's own)",
    )
    parser.add_argument("--json", type=Path)
    parser.add_argument(
        "--smoke", action="store_true", help="synthetic demos, one candidate, 2 folds: seconds"
    )
    args = parser.parse_args()
    if args.dataset is None and not args.smoke:
        parser.error("the dataset is required (or --smoke)")

    observe = parse_groups(args.observe)
    joints = load_robot_settings("baxter_left").recorded_arm_joints
    model_settings: dict = {}
    if args.smoke:  # one candidate at one ratio; nothing else selected inside ``fit``
        ds = make_synthetic_dataset(n_tasks=2, n_demos=4, seed=0)
        args.dataset, args.n_train, args.folds, args.study = Path(ds.root), 4, 2, "start"
        model_settings = {"head": False, "handover": False, "coupling": "all", "noise": 10.0}
    else:
        ds = load_dataset(args.dataset, frames=skeleton_frames(observe) or None, robot_joints=joints)
    pool = {task: demos[: args.n_train] for task, demos in ds.demos.items()}
    if args.study == "settings":
        grid = itertools.product([0.1, 0.2, 0.4], [5.0, 10.0, 20.0], [0.8, 0.9, 1.0], [90.0, 100.0])
        candidates = [
            {"blend_s": b, "replan_rate_hz": r, "freeze_phase": f, "percentile": p} for b, r, f, p in grid
        ]
        ratios = [0.1, 0.2]
    else:
        base = {
            "blend_s": args.blend,
            "replan_rate_hz": args.replan,
            "freeze_phase": args.freeze,
            "percentile": args.percentile,
        }
        if args.study == "start":
            candidates = [base]
            ratios = [0.2] if args.smoke else [0.1, 0.2, 0.3]
        elif args.study == "estimates":
            candidates = [{**base, "handover_estimates": e} for e in (False, True)]
            ratios = [0.1, 0.2]
        else:
            candidates = [{**base, "condition_noise": nu} for nu in args.noises]
            ratios = [0.1, 0.2]
    work = []
    for fold in range(args.folds):
        test = [d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds == fold]
        train = [d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds != fold]
        work.append((fold, train, test, candidates, ratios, observe, model_settings))
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("fork")) as ex:
            rows = [r for part in ex.map(_fold, work) for r in part]
    else:
        rows = [r for part in map(_fold, work) for r in part]
    keys = ("blend_s", "replan_rate_hz", "freeze_phase", "percentile")
    keys += {
        "settings": (),
        "start": ("ratio",),
        "noise": ("condition_noise",),
        "estimates": ("handover_estimates",),
    }[args.study]
    print(
        f"{args.dataset.name}, observing {args.observe}: {len(rows)} replays, {args.folds}-fold CV on "
        f"the first {args.n_train} demos per task"
    )
    print(" | ".join(keys) + " | err [cm] | final [cm] | delay [s] | max ratio | refused")
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in keys), []).append(r)
    summary = []
    for key, rs in groups.items():
        s = {
            **dict(zip(keys, key, strict=True)),
            "err": float(np.median([r["err"] for r in rs])),
            "final": float(np.median([r["final"] for r in rs])),
            "delay": float(np.median([r["delay"] for r in rs])),
            "ratio_max": float(max(r["ratio_max"] for r in rs)),
            "refused": int(sum(r["refused"] for r in rs)),
            "n": len(rs),
        }
        summary.append(s)
        print(
            " | ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in key)
            + f" | {s['err']:.2f} | {s['final']:.2f} | {s['delay']:.2f} "
            f"| {s['ratio_max']:.3f} | {s['refused']}"
        )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {"dataset": str(args.dataset), "observe": observe, "summary": summary, "rows": rows}, indent=1
            )
        )


if __name__ == "__main__":
    main()
