"""Choose model settings by cross-validation on training demos only.

The model's defaults that are not fitted inside ``IProMP.fit`` (EMG in log
space or linear; how much of the covariance is pooled across tasks) were
chosen with this script: k-fold cross-validation over the first ``--n-train``
demos of every task (in the authors' order), which are training demos in
every cell of the paper's protocol, so no test demo of that protocol is used.

    python benchmarks/settings_cv.py ../shared/datasets/chen2017_handover [--n-train 10] [--folds 5]

Prints, per setting, recognition accuracy and the median hand-over position
error of the conditioned prediction and of the prior, at observation ratios
0.1 and 0.2, observing orientation + EMG.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin.kinematics import ee_positions
from ipromp_pin.readers import load_dataset
from ipromp_pin.recognition import IProMP
from ipromp_pin.robot import load_robot


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--n-train", type=int, default=10)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--observe", default="orientation,emg")
    parser.add_argument(
        "--study", choices=["scaling", "basis"], default="scaling", help="which settings to compare"
    )
    args = parser.parse_args()

    observe = args.observe.split(",")
    ds = load_dataset(args.dataset)
    robot = load_robot("baxter_left")
    pool = {task: demos[: args.n_train] for task, demos in ds.demos.items()}
    if args.study == "scaling":
        settings = [
            {"log_groups": lg, "pooling": p} for lg, p in itertools.product([(), ("emg",)], [0.0, 0.5, 1.0])
        ]
    else:
        settings = [{"n_basis": k} for k in (11, 16, 21, 31)]
    print(f"{args.folds}-fold CV over the first {args.n_train} demos of each task of {args.dataset.name}")
    print(f"{'setting':<28}{'ratio':>7}{'accuracy':>10}{'hand-over cm':>14}{'prior cm':>10}")
    with threadpool_limits(1):
        for s in settings:
            for ratio in (0.1, 0.2):
                correct, errors, prior_errors = [], [], []
                for fold in range(args.folds):
                    test = [
                        d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds == fold
                    ]
                    train = [
                        d for demos in pool.values() for i, d in enumerate(demos) if i % args.folds != fold
                    ]
                    model = IProMP(observe=observe, **s).fit(train)
                    for d in test:
                        p = model.predict(d.head(ratio, groups=observe))
                        correct.append(p.task == d.task)
                        if p.task == d.task:
                            x = ee_positions(
                                robot, np.stack([d.groups["robot"][-1], p.q_mean[-1], p.q_prior_mean[-1]])
                            )
                            errors.append(np.linalg.norm(x[1] - x[0]) * 100)
                            prior_errors.append(np.linalg.norm(x[2] - x[0]) * 100)
                text = " ".join(f"{k}={'+'.join(v) if isinstance(v, tuple) else v}" for k, v in s.items())
                print(
                    f"{text:<28}{ratio:>7.1f}"
                    f"{np.mean(correct):>10.3f}{np.median(errors):>14.2f}{np.median(prior_errors):>10.2f}"
                )


if __name__ == "__main__":
    main()
