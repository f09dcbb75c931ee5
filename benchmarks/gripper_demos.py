"""A model trained on gripper demos (the robot side as a gripper pose path, no joints) against the
same model trained on the recorded joints, both executed on another arm through the gripper.

The gripper demos are the recordings' own: Baxter's forward kinematics of the recorded joints
(:func:`ipromp_pin.robot.recordings.as_gripper_demos`), what a recording without robot joints would
give. Per fold, ``N_HELD`` demos of every task (evenly spread) are held out; both models train on the
rest (the joint model with Baxter's kinematics, as ``ipromp-pin train`` does); each held-out demo's
first ``RATIO`` of the human motion is planned on the arm (``ipromp_pin.plan``, every check, no
retreat). Reported: the training time of both (median over folds, and the ratio), and per held-out
demo the distance between the two plans' hand-over gripper positions and each one's distance from
the recorded hand-over (Baxter's gripper at the demo's last sample), with how many plans passed.

    PYTHONPATH=. python benchmarks/gripper_demos.py ../shared/datasets/handover_20171128 [--robot panda]
        [--folds 3] [--observe orientation,emg]

Without a dataset: the built-in synthetic demos (seed 0). ``--smoke``: 3 tasks x 6 synthetic demos, one
fold, one held-out demo per task.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ipromp_pin import plan
from ipromp_pin.data import GRIPPER, ROBOT, parse_groups
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, gripper_kinematics, load_robot
from ipromp_pin.robot.recordings import as_gripper_demos, read_recordings

N_HELD = 2
"""Held-out demos per task and fold."""

RATIO = 0.2
"""Observed fraction of each held-out demo."""


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dataset", type=Path, nargs="?")
    p.add_argument("--smoke", action="store_true")
    p.add_argument("--robot", default="panda")
    p.add_argument("--folds", type=int, default=3)
    p.add_argument("--observe", default="orientation,emg")
    args = p.parse_args()
    observe = parse_groups(args.observe)
    baxter, arm = load_robot("baxter_left"), load_robot(args.robot)
    if args.dataset is None or args.smoke:
        ds = make_synthetic_dataset(n_demos=6 if args.smoke else 20, seed=0)
        args.folds = 1 if args.smoke else args.folds
    else:
        ds = read_recordings(args.dataset, baxter)
    n_held = 1 if args.smoke else N_HELD
    label = "synthetic" if args.dataset is None or args.smoke else args.dataset.name
    gds = as_gripper_demos(ds, baxter)
    kin = gripper_kinematics(baxter)._asdict()
    times: dict[str, list[float]] = {"joints": [], "gripper": []}
    rows = []
    for fold in range(args.folds):
        held = {}
        for task, demos in ds.demos.items():
            idx = np.linspace(0, len(demos) - 1, n_held * args.folds).round().astype(int)
            held[task] = set(idx[fold :: args.folds].tolist())
        train_j = [d for t, ds_ in ds.demos.items() for i, d in enumerate(ds_) if i not in held[t]]
        train_g = [d for t, ds_ in gds.demos.items() for i, d in enumerate(ds_) if i not in held[t]]
        t0 = time.perf_counter()
        model_j = IProMP(observe=observe).fit(train_j, **kin)
        t1 = time.perf_counter()
        model_g = IProMP(observe=observe, robot_group=GRIPPER).fit(train_g)
        t2 = time.perf_counter()
        times["joints"].append(t1 - t0)
        times["gripper"].append(t2 - t1)
        for task, indices in held.items():
            for i in sorted(indices):
                demo = ds.demos[task][i]
                obs_j = demo.head(RATIO, groups=observe)
                obs_g = gds.demos[task][i].head(RATIO, groups=observe)
                pj = plan(model_j, obs_j, arm, retreat=False)
                pg = plan(model_g, obs_g, arm, retreat=False)
                truth = ee_positions(baxter, demo.groups[ROBOT][-1:])[0]
                hj, hg = pj.approach.handover_pose[:3], pg.approach.handover_pose[:3]
                rows.append(
                    (
                        f"{task}/{demo.name}",
                        np.linalg.norm(hg - hj) * 100,
                        np.linalg.norm(hj - truth) * 100,
                        np.linalg.norm(hg - truth) * 100,
                        pj.passed,
                        pg.passed,
                    )
                )
                print(
                    f"fold {fold} {rows[-1][0]}: gripper vs joint model {rows[-1][1]:.2f} cm; "
                    f"from the recorded hand-over: joint {rows[-1][2]:.2f} cm, gripper {rows[-1][3]:.2f} cm; "
                    f"passed {pj.passed}/{pg.passed}",
                    flush=True,
                )
    a = np.array([r[1:4] for r in rows])
    tj, tg = np.median(times["joints"]), np.median(times["gripper"])
    print(f"\n{label}, {args.robot}, {args.folds} folds, {len(rows)} held-out demos, observe {observe}")
    print(
        f"training: joints {tj:.2f} s, gripper {tg:.2f} s (median over folds), "
        f"ratio gripper/joints {tg / tj:.2f}"
    )
    for k, name in enumerate(
        ["gripper vs joint model", "joint model vs recorded", "gripper model vs recorded"]
    ):
        print(
            f"{name}: median {np.median(a[:, k]):.2f} cm, mean {a[:, k].mean():.2f} cm, "
            f"max {a[:, k].max():.2f} cm"
        )
    print(
        f"passed: joint model {sum(r[4] for r in rows)}/{len(rows)}, "
        f"gripper model {sum(r[5] for r in rows)}/{len(rows)}"
    )


if __name__ == "__main__":
    main()
