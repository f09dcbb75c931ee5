"""Paired speed comparison of this checkout's inference with another checkout's (paper setting).

Run ``taskset -c 0 python benchmarks/ab_compare.py OTHER`` where ``OTHER`` is a checkout of an
earlier commit (``git worktree add ../old <commit>``). Its package is copied under the name
``ipromp_other`` and imported beside this one, both models are fitted on the same synthetic
demos, and their full updates (10 % and 20 % observed) and streaming updates are called
alternately in one process, so that the drift of a shared machine's speed affects both alike:
the paired differences isolate what the code changed. Prints medians in [us] and their ratios;
checks first that both give the same prediction.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from inference import stream_update_times
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
OBSERVE = ["orientation", "emg"]


def fitted(package: str, n_tasks: int):
    """Model of ``package`` fitted on 20 synthetic demos per task, and its held-out demos."""
    synthetic = __import__(f"{package}.synthetic", fromlist=["make_synthetic_dataset"])
    recognition = __import__(f"{package}.recognition", fromlist=["IProMP"])
    ds = synthetic.make_synthetic_dataset(n_tasks=n_tasks, n_demos=22, seed=1)
    train = type(ds)(ds.root, {t: d[:20] for t, d in ds.demos.items()})
    test = {t: d[20:] for t, d in ds.demos.items()}
    return recognition.IProMP(OBSERVE, noise=10.0, blas_threads=None).fit(train), test


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", help="checkout of the commit to compare with")
    ap.add_argument("--tasks", type=int, default=3, help="number of tasks (default 3)")
    ap.add_argument("--repeats", type=int, default=2000, help="full updates per ratio and version")
    ap.add_argument(
        "--allow-different",
        action="store_true",
        help="compare speed even when the checkouts' models predict differently (a model change)",
    )
    args = ap.parse_args(argv)
    source = Path(args.other) / "ipromp_pin"
    if not (source / "__init__.py").is_file():
        ap.error(f"{args.other}: no ipromp_pin package there")
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(source, Path(tmp) / "ipromp_other", ignore=shutil.ignore_patterns("__pycache__"))
        sys.path[:0] = [tmp, str(ROOT)]
        with threadpool_limits(1):
            other, other_test = fitted("ipromp_other", args.tasks)  # compiles its kernels (cold)
            this, this_test = fitted("ipromp_pin", args.tasks)
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
            obs_o = other_test[other.tasks_[0]][0].head(0.2, OBSERVE)
            obs_t = this_test[this.tasks_[0]][0].head(0.2, OBSERVE)
            s_o, s_t = [], []
            for _ in range(10):  # alternate blocks of 3 streams
                s_o += stream_update_times(other, obs_o, 3)
                s_t += stream_update_times(this, obs_t, 3)
            a, b = np.median(s_o) * 1e6, np.median(s_t) * 1e6
            print(f"  streaming update: {a:.1f} -> {b:.1f} (ratio {b / a:.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
