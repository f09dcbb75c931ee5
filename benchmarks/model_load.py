"""Model file loading: this checkout (checked: directory, array headers, values) against another's.

Run ``taskset -c 0 python benchmarks/model_load.py OTHER`` where ``OTHER`` is a checkout of an
earlier commit (``git worktree add ../old <commit>``). Its package is copied under the name
``ipromp_other`` and imported beside this one. A model is fitted on the synthetic demos (paper
setting: 3 tasks x 20 demos, orientation + EMG) and saved once; then both versions load that same
file alternately, ``--repeats`` times each, in one process, so that a shared machine's drift
affects both alike. Prints the median load time of each in [ms], the median of the paired
differences and the file's size. Both loaded models must predict the same.

``--smoke`` compares this checkout with itself (numpy kernels, numba's JIT off: no compile) on a small model
loaded a few times: seconds; the test suite runs it so that the script cannot silently rot.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from checkouts import OTHER, ROOT, add_other, first_module, smoke_kernels

OBSERVE = ["orientation", "emg"]
SMOKE_MODEL = {"head": False, "handover": False, "coupling": "all"}
"""Model settings of ``--smoke`` (nothing selected by cross-validation inside ``fit``: seconds)."""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", nargs="?", help="checkout of the commit to compare with")
    ap.add_argument("--repeats", type=int, default=200, help="loads per version (default 200)")
    ap.add_argument("--smoke", action="store_true", help="this checkout against itself, tiny: seconds")
    args = ap.parse_args(argv)
    if args.smoke:
        args.other = args.other or str(ROOT)
        args.repeats = 3
    elif args.other is None:
        ap.error("the checkout to compare with is required (or --smoke)")
    if not (Path(args.other) / "ipromp_pin" / "__init__.py").is_file():
        ap.error(f"{args.other}: no ipromp_pin package there")
    n_tasks, n_train = (2, 4) if args.smoke else (3, 20)
    with tempfile.TemporaryDirectory() as tmp:
        add_other(Path(args.other), Path(tmp))
        if args.smoke:
            smoke_kernels(OTHER, "ipromp_pin")
        OtherIProMP = first_module(OTHER, "promp", "recognition").IProMP
        other_synthetic = first_module(OTHER, "readers.synthetic", "synthetic").make_synthetic_dataset

        from ipromp_pin.promp import IProMP
        from ipromp_pin.readers.synthetic import make_synthetic_dataset

        ds = make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 1, seed=1)
        train = type(ds)(ds.root, {t: d[:n_train] for t, d in ds.demos.items()})
        model = IProMP(OBSERVE, noise=10.0, **(SMOKE_MODEL if args.smoke else {})).fit(train)
        path = Path(tmp) / "model.npz"
        model.save(path)
        obs = ds.demos[model.tasks_[0]][n_train].head(0.2, OBSERVE)
        other_ds = other_synthetic(n_tasks=n_tasks, n_demos=n_train + 1, seed=1)
        other_obs = other_ds.demos[model.tasks_[0]][n_train].head(0.2, OBSERVE)
        this, other = IProMP.load(path), OtherIProMP.load(path)  # warm both (imports, caches)
        if not np.array_equal(this.predict(obs).q_mean, other.predict(other_obs).q_mean):
            print("the two versions predict differently from the same file")
            return 1
        clock = time.perf_counter
        t_this, t_other = [], []
        for _ in range(args.repeats):
            t0 = clock()
            OtherIProMP.load(path)
            t1 = clock()
            IProMP.load(path)
            t2 = clock()
            t_other.append(t1 - t0)
            t_this.append(t2 - t1)
        a, b = np.array(t_other) * 1e3, np.array(t_this) * 1e3
        print(f"model file {path.stat().st_size / 1e6:.2f} MB, {args.repeats} loads each (median [ms])")
        print(f"  other checkout: {np.median(a):.2f} ms")
        print(f"  this checkout:  {np.median(b):.2f} ms")
        print(f"  paired difference (this - other): median {np.median(b - a):+.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
