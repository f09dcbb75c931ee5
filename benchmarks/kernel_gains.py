"""What each compiled inference kernel gains over its numpy version, and what compiling it costs.

Run ``taskset -c 0 python benchmarks/kernel_gains.py [--compile]``. The default model (paper setting,
3 tasks of 20 synthetic demos, as ``ab_compare.py`` fits it) is fitted once per backend and then
predicts 20 % of a held-out demo ``--updates`` times, the two backends' updates alternating; every
kernel call goes through a timer (:func:`ipromp_pin.promp.compiled.kernels` hands out a timed copy of
each backend's module). Prints per kernel the calls of one fit and their total time with each
backend, then the calls per update and the median time per call with each, and the ratios.
``--compile`` also runs one fit and prediction in a fresh process with an empty numba cache and
prints each kernel's first call there (its compile, or its load from the cache for a kernel
another kernel compiled with it), and the process's CPU time. ``--smoke``: 2 tasks of 4 demos,
a few updates, the numpy kernels in both columns (nothing compiled): seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import types
from collections import defaultdict

import numpy as np
from checkouts import ROOT
from threadpoolctl import threadpool_limits

OBSERVE = ["orientation", "emg"]


def timed_module(module: types.ModuleType, record: dict[str, list[float]]) -> types.SimpleNamespace:
    """A copy of ``module`` whose functions append their call times in [s] to ``record[name]``."""
    out = types.SimpleNamespace()
    for name in dir(module):
        if name.startswith("__"):
            continue
        value = getattr(module, name)
        if callable(value) and not isinstance(value, type):

            def timed(*args, _f=value, _times=record[name], **kwargs):
                t0 = time.perf_counter()
                result = _f(*args, **kwargs)
                _times.append(time.perf_counter() - t0)
                return result

            value = timed
        setattr(out, name, value)
    return out


def measure(n_tasks: int, n_train: int, updates: int) -> tuple[dict, dict]:
    """Per backend, the kernels' call times of one fit and of ``updates`` full updates."""
    from ab_compare import training_data

    from ipromp_pin.promp import compiled

    fit_times: dict[str, dict[str, list[float]]] = {}
    update_times: dict[str, dict[str, list[float]]] = {}
    models = {}
    estimator, train, test = training_data("ipromp_pin", n_tasks, n_train)
    for backend in ("numba", "numpy"):
        fit_times[backend] = defaultdict(list)
        with compiled.use_kernels(backend):
            module = compiled.kernels()
            compiled._state["modules"][(compiled.INFERENCE, backend)] = timed_module(
                module, fit_times[backend]
            )
            try:
                models[backend] = estimator(OBSERVE, noise=10.0, blas_threads=None).fit(train)
            finally:
                compiled._state["modules"][(compiled.INFERENCE, backend)] = module
    obs = test[models["numba"].tasks_[0]][0].head(0.2, OBSERVE)
    timed = {}
    for backend in ("numba", "numpy"):
        update_times[backend] = defaultdict(list)
        with compiled.use_kernels(backend):
            timed[backend] = (compiled.kernels(), timed_module(compiled.kernels(), update_times[backend]))
    for i in range(updates + 2):
        for backend in ("numba", "numpy"):
            module, proxy = timed[backend]
            with compiled.use_kernels(backend):
                compiled._state["modules"][(compiled.INFERENCE, backend)] = proxy
                try:
                    models[backend].predict(obs)
                finally:
                    compiled._state["modules"][(compiled.INFERENCE, backend)] = module
            if i < 2:  # the first two updates load what is left to load
                for calls in update_times[backend].values():
                    calls.clear()
    return fit_times, update_times


def first_calls(n_tasks: int, n_train: int) -> dict:
    """In a fresh process with an empty numba cache: each kernel's first-call time in [s] during a
    fit and a prediction, and the process's CPU time."""
    code = f"""
import json, sys, time, collections
sys.path[:0] = [{str(ROOT / "benchmarks")!r}, {str(ROOT)!r}]
from kernel_gains import timed_module
from ab_compare import training_data
from ipromp_pin.promp import compiled
record = collections.defaultdict(list)
with compiled.use_kernels("numba"):
    compiled._state["modules"][(compiled.INFERENCE, "numba")] = timed_module(compiled.numba_kernels(), record)
    estimator, train, test = training_data("ipromp_pin", {n_tasks}, {n_train})
    model = estimator({OBSERVE!r}, noise=10.0, blas_threads=None).fit(train)
    model.predict(test[model.tasks_[0]][0].head(0.2, {OBSERVE!r}))
print(json.dumps({{"first": {{k: v[0] for k, v in record.items() if v}}, "cpu": time.process_time()}}))
"""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(ROOT)}
        done = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=3, help="number of tasks (default 3)")
    ap.add_argument("--updates", type=int, default=300, help="full updates per backend")
    ap.add_argument("--compile", action="store_true", help="also the first calls with an empty numba cache")
    ap.add_argument("--smoke", action="store_true", help="tiny, numpy kernels only: seconds")
    args = ap.parse_args(argv)
    n_train = 20
    if args.smoke:
        from ipromp_pin.promp import compiled, numpy_kernels

        compiled._state["modules"][(compiled.INFERENCE, "numba")] = numpy_kernels
        args.tasks, args.updates, n_train = 2, 3, 4
    with threadpool_limits(1):
        fit_times, update_times = measure(args.tasks, n_train, args.updates)
    print(f"{args.tasks} tasks of {n_train} synthetic demos; numba -> numpy")
    print("one fit: kernel, calls, total [ms] numba -> numpy (ratio)")
    called = [n for n, calls in fit_times["numba"].items() if calls]
    for name in sorted(called, key=lambda n: -sum(fit_times["numpy"].get(n, [0.0]))):
        a, b = sum(fit_times["numba"][name]) * 1e3, sum(fit_times["numpy"].get(name, [np.nan])) * 1e3
        print(
            f"  {name:16s} {len(fit_times['numba'][name]):6d} {a:9.1f} -> {b:9.1f} ({b / max(a, 1e-9):5.1f}x)"
        )
    print("full update, 20 % observed: kernel, calls per update, median per call [us] numba -> numpy (ratio)")
    called = [n for n, calls in update_times["numba"].items() if calls]
    for name in sorted(called, key=lambda n: -np.median(update_times["numba"][n])):
        a = float(np.median(update_times["numba"][name])) * 1e6
        b = float(np.median(update_times["numpy"].get(name, [np.nan]))) * 1e6
        per = len(update_times["numba"][name]) / args.updates
        print(f"  {name:16s} {per:4.1f} {a:8.1f} -> {b:8.1f} ({b / max(a, 1e-9):5.1f}x)")
    if args.compile and not args.smoke:
        cold = first_calls(args.tasks, n_train)
        cpu = cold["cpu"]
        print(f"empty numba cache: fit and prediction in a fresh process, CPU {cpu:.1f} s; first calls [s]")
        for name, seconds in sorted(cold["first"].items(), key=lambda kv: -kv[1]):
            print(f"  {name:16s} {seconds:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
