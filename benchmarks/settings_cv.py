"""Choose model settings by cross-validation on training demos only.

The model's defaults that are not fitted inside ``IProMP.fit`` (EMG in log
space or linear; how much of the covariance is pooled across tasks) were
chosen with this script, and the ``coupling`` study compares the observed
groups coupled to the robot (``IProMP(coupling=...)``, chosen inside ``fit``
by default): k-fold cross-validation over the first ``--n-train`` demos of
every task (in the authors' order), which are training demos in every cell of
the paper's protocol with at least that many training demos.

    python benchmarks/settings_cv.py ../shared/datasets/chen2017_handover [--n-train 10] [--folds 5]
        [--study scaling|basis|coupling]

Prints, per setting, recognition accuracy and, over the correctly recognised
held-out demos, the median and mean hand-over position error in [cm] and the
mean joint RMSE over the unobserved part in [rad], each for the conditioned
prediction and for the prior, at observation ratios 0.1 and 0.2, observing
orientation + EMG. ``--smoke`` (no dataset): one setting, ratio 0.2, 2 folds over 4 synthetic
demos per task: seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin import IProMP
from ipromp_pin.evaluation.evaluate import score_trial
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path, nargs="?", help="dataset folder (not with --smoke)")
    parser.add_argument("--n-train", type=int, default=10)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--observe", default="orientation,emg")
    parser.add_argument(
        "--study",
        choices=["scaling", "basis", "coupling"],
        default="scaling",
        help="which settings to compare",
    )
    parser.add_argument("--smoke", action="store_true", help="synthetic demos, one setting, 2 folds: seconds")
    args = parser.parse_args()
    if args.dataset is None and not args.smoke:
        parser.error("the dataset is required (or --smoke)")

    observe = args.observe.split(",")
    if args.smoke:
        ds = make_synthetic_dataset(n_tasks=2, n_demos=4, seed=0)
        args.n_train, args.folds, args.dataset = 4, 2, Path(ds.root)
    else:
        ds = load_dataset(args.dataset)
    robot = load_robot("baxter_left")
    pool = {task: demos[: args.n_train] for task, demos in ds.demos.items()}
    if args.study == "scaling":
        settings = [
            {"log_groups": lg, "pooling": p} for lg, p in itertools.product([(), ("emg",)], [0.0, 0.5, 1.0])
        ]
    elif args.study == "basis":
        settings = [{"n_basis": k} for k in (11, 16, 21, 31)]
    else:
        settings = [{"coupling": c} for c in ("all", *[(g,) for g in observe], "auto")]
    ratios = (0.1, 0.2)
    fixed = {}
    if args.smoke:  # one setting, one ratio, nothing else selected inside ``fit``
        settings, ratios, fixed = settings[:1], (0.2,), {"head": False, "handover": False, "noise": 10.0}
    print(f"{args.folds}-fold CV over the first {args.n_train} demos of each task of {args.dataset.name}")
    print(
        f"{'setting':<28}{'ratio':>7}{'accuracy':>10}{'hand-over cm median':>22}"
        f"{'hand-over cm mean':>20}{'joint RMSE rad':>18}"
    )

    def fk(q: np.ndarray) -> np.ndarray:
        return ee_positions(robot, q)

    with threadpool_limits(1):
        for s in settings:
            for ratio in ratios:
                correct, trials = [], []
                for fold in range(args.folds):
                    test = [
                        d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds == fold
                    ]
                    train = [
                        d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds != fold
                    ]
                    model = IProMP(observe=observe, **fixed, **s).fit(train)
                    for d in test:
                        r = score_trial(model.predict(d.head(ratio, groups=observe)), d, ratio, fk)
                        correct.append(r.correct)
                        if r.correct:
                            trials.append(r)
                ho = np.array([r.handover_error_cm for r in trials])
                ho_prior = np.array([r.handover_error_prior_cm for r in trials])
                rmse = np.mean([r.joint_rmse_rad for r in trials])
                rmse_prior = np.mean([r.joint_rmse_prior_rad for r in trials])
                text = " ".join(f"{k}={'+'.join(v) if isinstance(v, tuple) else v}" for k, v in s.items())
                print(
                    f"{text:<28}{ratio:>7.1f}{np.mean(correct):>10.3f}"
                    f"{np.median(ho):>11.2f} vs {np.median(ho_prior):>5.2f}"
                    f"{np.mean(ho):>9.2f} vs {np.mean(ho_prior):>5.2f}"
                    f"{rmse:>9.4f} vs {rmse_prior:.4f}"
                )


if __name__ == "__main__":
    main()
