"""Paired speed comparison of this checkout's inference with another checkout's (paper setting).

Run ``taskset -c 0 python benchmarks/ab_compare.py OTHER`` where ``OTHER`` is a checkout of an
earlier commit (``git worktree add ../old <commit>``). Its package is copied under the name
``ipromp_other`` and imported beside this one, both models are fitted on the same synthetic
demos, and their full updates (10 % and 20 % observed) and streaming updates are called
alternately in one process, so that the drift of a shared machine's speed affects both alike:
the paired differences isolate what the code changed. Prints medians in [us] and their ratios;
checks first that both give the same prediction.

``--smoke`` compares this checkout with itself (numpy kernels, numba's JIT off: no compile) on 2
tasks of a few demos, with a few calls (streams of 5 % of a demo): seconds; the test suite runs it
so that the script cannot silently rot.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from checkouts import OTHER, ROOT, add_other, first_module, smoke_kernels
from inference import stream_update_times
from threadpoolctl import threadpool_limits

OBSERVE = ["orientation", "emg"]


SMOKE_MODEL = {"head": False, "handover": False, "coupling": "all"}
"""Model settings of ``--smoke`` (nothing selected by cross-validation inside ``fit``: seconds)."""


def fitted(package: str, n_tasks: int, n_train: int = 20, **settings):
    """Model of ``package`` fitted on ``n_train`` synthetic demos per task (``settings``: further
    ``IProMP`` parameters), and its 2 held-out demos."""
    synthetic = first_module(package, "readers.synthetic", "synthetic")
    estimator = first_module(package, "promp", "recognition")
    ds = synthetic.make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 2, seed=1)
    train = type(ds)(ds.root, {t: d[:n_train] for t, d in ds.demos.items()})
    test = {t: d[n_train:] for t, d in ds.demos.items()}
    return estimator.IProMP(OBSERVE, noise=10.0, blas_threads=None, **settings).fit(train), test


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", nargs="?", help="checkout of the commit to compare with")
    ap.add_argument("--tasks", type=int, default=3, help="number of tasks (default 3)")
    ap.add_argument("--repeats", type=int, default=2000, help="full updates per ratio and version")
    ap.add_argument(
        "--allow-different",
        action="store_true",
        help="compare speed even when the checkouts' models predict differently (a model change)",
    )
    ap.add_argument("--smoke", action="store_true", help="this checkout against itself, tiny: seconds")
    args = ap.parse_args(argv)
    if args.smoke:
        args.other = args.other or str(ROOT)
        args.tasks, args.repeats = 2, 3
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
            print(f"paper setting, {args.tasks} tasks; medians in us (other -> this checkout)")
            for ratio in (0.1, 0.2):
                obs_o = other_test[other.tasks_[0]][0].head(ratio, OBSERVE)
                obs_t = this_test[this.tasks_[0]][0].head(ratio, OBSERVE)
                p_o, p_t = other.predict(obs_o), this.predict(obs_t)
                if not (
                    np.allclose(p_o.q_mean, p_t.q_mean, rtol=1e-9, atol=1e-12)
                    and np.allclose(p_o.posterior, p_t.posterior, rtol=1e-9, atol=1e-12)
                ):
                    print(f"  ratio {ratio}: the two checkouts predict differently")
                    if not args.allow_different:
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
