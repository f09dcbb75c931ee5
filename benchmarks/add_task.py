"""A task added to a trained model (``IProMP.add_task``) against a full refit with the same demos.

For every task of a dataset in turn: train on the first ``--n-train`` demos of the other tasks (with
the robot's kinematics, as ``train`` does), add the task from its first N demos (N in ``--new``),
and refit on the same demos from scratch; report the task accuracy on every task's remaining demos
(observed for the first 10 % and 20 %), and the time of the addition and of the refit (medians over
the tasks, and their ratio). Demos without one of the observed groups (a recording without the
tracked skeleton) are left out.

    python benchmarks/add_task.py ../shared/datasets/chen2017_handover --observe orientation,emg
    python benchmarks/add_task.py ../shared/datasets/handover_20171128 --observe /left_hand_1,emg

``--smoke`` (no dataset): 3 synthetic tasks of 8 demos, 4 training and 3 new demos, the first task
added only: seconds.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from ipromp_pin.data import parse_groups, skeleton_frames
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import gripper_kinematics, load_robot

RATIOS = (0.1, 0.2)


def accuracy(model: IProMP, test: list, observe: list[str]) -> list[float]:
    """Task accuracy on ``test`` observed for the first 10 % and 20 %."""
    out = []
    for ratio in RATIOS:
        recs = model.recognise([d.head(ratio, observe) for d in test])
        out.append(float(np.mean([r.task == d.task for r, d in zip(recs, test, strict=True)])))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", nargs="?")
    ap.add_argument("--observe", default="orientation,emg")
    ap.add_argument("--n-train", type=int, default=15, help="training demos of every fitted task")
    ap.add_argument("--new", default="5,10", help="numbers of demos the added task is learned from")
    ap.add_argument("--smoke", action="store_true")
    args = ap.parse_args()
    observe = parse_groups(args.observe)
    news = [int(n) for n in args.new.split(",")]
    if args.smoke:
        ds, args.n_train, news = make_synthetic_dataset(n_tasks=3, n_demos=8, seed=1), 4, [3]
    else:
        ds = load_dataset(args.dataset, frames=skeleton_frames(observe) or None)
    kin = gripper_kinematics(load_robot("baxter_left"))._asdict()
    demos = {t: [d for d in v if all(g in d.groups for g in observe)] for t, v in ds.demos.items()}
    head = f"{'task added':<18} {'N':>3}  {'add acc 10%/20%':>16}  {'refit acc 10%/20%':>18}"
    print(f"{head}  {'add s':>6}  {'refit s':>7}")
    saved = Path(tempfile.mkdtemp()) / "trained.npz"
    times: dict[int, list[tuple[float, float]]] = {n: [] for n in news}
    gaps: dict[int, list[float]] = {n: [] for n in news}
    for new in list(demos)[:1] if args.smoke else demos:
        others = [d for t, v in demos.items() if t != new for d in v[: args.n_train]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            IProMP(observe=observe).fit(others, **kin).save(saved)
            for n in news:
                test = [d for t, v in demos.items() for d in v[(n if t == new else args.n_train) :]]
                grown = IProMP.load(saved)  # the trained model, afresh for every addition
                t0 = time.perf_counter()
                grown.add_task(demos[new][:n])
                t_add = time.perf_counter() - t0
                t0 = time.perf_counter()
                refit = IProMP(observe=observe).fit(others + demos[new][:n], **kin)
                t_refit = time.perf_counter() - t0
                a, r = accuracy(grown, test, observe), accuracy(refit, test, observe)
                times[n].append((t_add, t_refit))
                gaps[n] += [ri - ai for ai, ri in zip(a, r, strict=True)]
                print(
                    f"{new:<18} {n:>3}  {a[0]:>7.3f} / {a[1]:.3f}  {r[0]:>8.3f} / {r[1]:.3f}  "
                    f"{t_add:>6.2f}  {t_refit:>7.2f}"
                )
    for n in news:
        t = np.array(times[n])
        print(
            f"N={n}: accuracy of the refit minus the addition: median {np.median(gaps[n]):+.3f}, "
            f"largest {max(gaps[n]):+.3f}; time median {np.median(t[:, 0]):.2f} s vs "
            f"{np.median(t[:, 1]):.2f} s: {np.median(t[:, 0] / t[:, 1]):.3f} of a refit"
        )


if __name__ == "__main__":
    main()
