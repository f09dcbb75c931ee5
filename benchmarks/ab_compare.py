"""Paired speed comparison of this checkout's inference with another checkout's (paper setting).

Run ``taskset -c 0 python benchmarks/ab_compare.py OTHER`` where ``OTHER`` is a checkout of an
earlier commit (``git worktree add ../old <commit>``). Its package is copied under the name
``ipromp_other`` and imported beside this one, both models are fitted on the same synthetic
demos, and their full updates (10 % and 20 % observed) and streaming updates are called
alternately in one process, so that the drift of a shared machine's speed affects both alike:
the paired differences isolate what the code changed. Prints medians in [us] and their ratios.
It also fits both versions alternately (``--fits``, paper setting, every cross-validation of the
default model) and prints the training time per task and the peak memory of a fit (``tracemalloc``).

Before timing it checks that both give the same prediction. Where they differ (a change of the
model on purpose, e.g. against the last release) it says so, with the largest difference, and
compares the speed anyway; ``--require-same`` makes a difference an error (exit 1) instead.

``--smoke`` compares this checkout with itself (numpy kernels, numba's JIT off: no compile) on 2
tasks of a few demos, with a few calls (streams of 5 % of a demo): seconds; the test suite runs it
so that the script cannot silently rot.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
from checkouts import OTHER, ROOT, add_other, first_module, smoke_kernels
from inference import stream_update_times
from threadpoolctl import threadpool_limits

OBSERVE = ["orientation", "emg"]


SMOKE_MODEL = {"head": False, "handover": False, "coupling": "all"}
"""Model settings of ``--smoke`` (nothing selected by cross-validation inside ``fit``: seconds)."""


def training_data(package: str, n_tasks: int, n_train: int = 20):
    """``package``'s estimator class, ``n_train`` synthetic demos per task and 2 held-out ones."""
    synthetic = first_module(package, "readers.synthetic", "synthetic")
    estimator = first_module(package, "promp", "recognition")
    ds = synthetic.make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 2, seed=1)
    train = type(ds)(ds.root, {t: d[:n_train] for t, d in ds.demos.items()})
    test = {t: d[n_train:] for t, d in ds.demos.items()}
    return estimator.IProMP, train, test


def fitted(package: str, n_tasks: int, n_train: int = 20, **settings):
    """Model of ``package`` fitted on ``n_train`` synthetic demos per task (``settings``: further
    ``IProMP`` parameters), and its 2 held-out demos."""
    estimator, train, test = training_data(package, n_tasks, n_train)
    return estimator(OBSERVE, noise=10.0, blas_threads=None, **settings).fit(train), test


def fit_times(packages: list[str], n_tasks: int, n_train: int, fits: int, **settings) -> list[tuple]:
    """Per package, (median training time per task in [s], peak memory of a fit in [MB], as
    ``benchmarks/inference.py`` measures them: ``fit`` alone): fits of the packages alternate,
    ``fits`` each (the peak from one more fit of each under ``tracemalloc``)."""
    data = {p: training_data(p, n_tasks, n_train) for p in packages}
    times: dict[str, list[float]] = {p: [] for p in packages}

    def fit(p: str) -> None:
        estimator, train, _ = data[p]
        estimator(OBSERVE, noise=10.0, blas_threads=None, **settings).fit(train)

    for _ in range(fits):
        for p in packages:
            t0 = time.perf_counter()
            fit(p)
            times[p].append((time.perf_counter() - t0) / n_tasks)
    out = []
    for p in packages:
        tracemalloc.start()
        fit(p)
        peak = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
        out.append((float(np.median(times[p])), peak))
    return out


def same_prediction(p_o, p_t) -> tuple[bool, float]:
    """Whether two predictions agree (robot mean and task posterior) and the largest difference of
    the robot means in [rad]."""
    same = np.allclose(p_o.q_mean, p_t.q_mean, rtol=1e-9, atol=1e-12) and np.allclose(
        p_o.posterior, p_t.posterior, rtol=1e-9, atol=1e-12
    )
    diff = float(np.max(np.abs(p_o.q_mean - p_t.q_mean))) if p_o.q_mean.shape == p_t.q_mean.shape else np.inf
    return bool(same), diff


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", nargs="?", help="checkout of the commit to compare with")
    ap.add_argument("--tasks", type=int, default=3, help="number of tasks (default 3)")
    ap.add_argument("--repeats", type=int, default=2000, help="full updates per ratio and version")
    ap.add_argument(
        "--require-same",
        action="store_true",
        help="exit 1 when the checkouts' models predict differently (default: say so and compare speed)",
    )
    ap.add_argument("--allow-different", action="store_true", help=argparse.SUPPRESS)  # the old default
    ap.add_argument("--fits", type=int, default=3, help="training runs per version (0: no training)")
    ap.add_argument("--smoke", action="store_true", help="this checkout against itself, tiny: seconds")
    args = ap.parse_args(argv)
    if args.smoke:
        args.other = args.other or str(ROOT)
        args.tasks, args.repeats, args.fits = 2, 3, min(args.fits, 1)
    elif args.other is None:
        ap.error("the checkout to compare with is required (or --smoke)")
    if not (Path(args.other) / "ipromp_pin" / "__init__.py").is_file():
        ap.error(f"{args.other}: no ipromp_pin package there")
    n_train, stream_blocks, streams = (4, 1, 1) if args.smoke else (20, 10, 3)
    settings = SMOKE_MODEL if args.smoke else {}
    with tempfile.TemporaryDirectory() as tmp:
        add_other(Path(args.other), Path(tmp))
        if args.smoke:
            smoke_kernels(OTHER, "ipromp_pin")
        with threadpool_limits(1):
            other, other_test = fitted(OTHER, args.tasks, n_train, **settings)  # compiles (cold)
            this, this_test = fitted("ipromp_pin", args.tasks, n_train, **settings)
            clock = time.perf_counter
            this_root = Path(sys.modules["ipromp_pin"].__file__ or "").resolve().parents[1]
            print(f"this checkout: {this_root}; other: {Path(args.other).resolve()}")
            if this_root != ROOT:
                print(f"  ipromp_pin was imported from {this_root}, not from {ROOT}")
                return 1
            print(f"paper setting, {args.tasks} tasks; medians in us (other -> this checkout)")
            for ratio in (0.1, 0.2):
                obs_o = other_test[other.tasks_[0]][0].head(ratio, OBSERVE)
                obs_t = this_test[this.tasks_[0]][0].head(ratio, OBSERVE)
                same, diff = same_prediction(other.predict(obs_o), this.predict(obs_t))
                if not same:
                    print(
                        f"  ratio {ratio}: the two checkouts predict differently (largest robot-mean "
                        f"difference {diff:.3g} rad): a model change; the speeds are compared anyway"
                    )
                    if args.require_same:
                        return 1
                t_o, t_t = [], []
                for _ in range(args.repeats):
                    t0 = clock()
                    other.predict(obs_o)
                    t1 = clock()
                    this.predict(obs_t)
                    t_o.append(t1 - t0)
                    t_t.append(clock() - t1)
                a, b = np.array(t_o) * 1e6, np.array(t_t) * 1e6
                print(
                    f"  full update, {ratio:.0%} observed: {np.median(a):.1f} -> {np.median(b):.1f}"
                    f" (median paired difference {np.median(a - b):.1f}, ratio {np.median(b / a):.3f})"
                )
            stream_ratio = 0.05 if args.smoke else 0.2
            obs_o = other_test[other.tasks_[0]][0].head(stream_ratio, OBSERVE)
            obs_t = this_test[this.tasks_[0]][0].head(stream_ratio, OBSERVE)
            s_o, s_t = [], []
            for _ in range(stream_blocks):  # alternate blocks of 3 streams
                s_o += stream_update_times(other, obs_o, streams)
                s_t += stream_update_times(this, obs_t, streams)
            a, b = np.median(s_o) * 1e6, np.median(s_t) * 1e6
            print(f"  streaming update: {a:.1f} -> {b:.1f} (ratio {b / a:.3f})")
            if args.fits > 0:
                (t_o, m_o), (t_t, m_t) = fit_times(
                    [OTHER, "ipromp_pin"], args.tasks, n_train, args.fits, **settings
                )
                print(
                    f"  training per task: {t_o * 1e3:.0f} -> {t_t * 1e3:.0f} ms (ratio {t_t / t_o:.3f}); "
                    f"peak memory of a fit: {m_o:.1f} -> {m_t:.1f} MB"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
