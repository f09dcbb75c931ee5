"""Where the time of an update goes: stage timers inside back-to-back updates (paper setting).

Run ``taskset -c 0 python benchmarks/profile_update.py`` (``--smoke``: 2 tasks of 4 demos, a few
calls, seconds: what the test suite runs). A full update is timed stage by stage
through the calls that :meth:`IProMP.predict` makes (input checks, basis statistics, the likelihood
of every (task, candidate) pair, the posteriors, the conditioning); a streaming update is split into
its compiled kernels (each call timed) and the rest (Python). Medians in [us]; the stages of a full
update add up to slightly less than a full update, which has one more level of calls.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from inference import OBSERVE, split, stream_update_times, warm_up
from threadpoolctl import threadpool_limits

import ipromp_pin.promp.compiled as compiled
from ipromp_pin import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset

STREAM_KERNELS = ("stream_sample", "sherman_morrison", "stream_group", "finish_soa", "recognition")


def full_update_stages(model: IProMP, obs, repeats: int = 2000) -> dict[str, float]:
    """Median time in [us] of each stage of :meth:`IProMP.predict` on ``obs``."""
    predictor = model.predictor_
    engine = predictor.engine
    clock = time.perf_counter
    rows = []
    for _ in range(repeats):
        t0 = clock()
        parts, t_last = predictor.encode(obs)
        t1 = clock()
        stats = [engine.part_stats(p) for p in parts]
        t2 = clock()
        loglik = engine.log_likelihood(stats, t_last)
        t3 = clock()
        rec = predictor.recognition_from_loglik(loglik, t_last)
        t4 = clock()
        predictor.conditioner.condition(rec, parts)
        t5 = clock()
        rows.append([t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t5 - t0])
    med = np.median(np.array(rows), axis=0) * 1e6
    names = ["input checks", "basis statistics", "pair likelihoods", "posteriors", "conditioning", "total"]
    return dict(zip(names, med, strict=True))


class _TimedKernels:
    """The kernels module with the streaming kernels' calls timed."""

    def __init__(self, kernels) -> None:
        self._k = kernels
        self.times: dict[str, list[float]] = {n: [] for n in STREAM_KERNELS}

    def __getattr__(self, name: str):
        fn = getattr(self._k, name)
        if name not in STREAM_KERNELS:
            return fn
        times = self.times[name]

        def timed(*args):
            t0 = time.perf_counter()
            out = fn(*args)
            times.append(time.perf_counter() - t0)
            return out

        return timed


def streaming_stages(model: IProMP, obs, passes: int = 30) -> dict[str, float]:
    """Median time in [us] of a streaming update and the per-update time of each kernel."""
    kernels = compiled.numba_kernels()  # the streaming kernels are the compiled ones on every backend
    timed = _TimedKernels(kernels)
    previous = compiled.set_kernel_backend("numba")
    compiled._state["numba"] = timed  # the streams created below call the timed kernels
    try:
        updates = stream_update_times(model, obs, passes)
    finally:
        compiled._state["numba"] = kernels
        compiled.set_kernel_backend(previous)
    n = len(updates) + 2 * passes  # every update calls the kernels, the first two included
    out = {"update (median)": float(np.median(updates)) * 1e6}
    for name, ts in timed.times.items():
        out[f"{name} (per update)"] = float(np.sum(ts)) / n * 1e6
    return out


def main(argv: list[str] | None = None) -> int:
    smoke = "--smoke" in (sys.argv[1:] if argv is None else argv)  # 2 tasks of 4 demos, few calls
    with threadpool_limits(1):
        if not smoke:
            warm_up()
        n_tasks, n_train = (2, 4) if smoke else (3, 20)
        train, test = split(make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 2, seed=1), n_train)
        settings = {"head": False, "handover": False} if smoke else {}
        model = IProMP(OBSERVE, noise=10.0, blas_threads=None, **settings).fit(train)
        obs = test[model.tasks_[0]][0].head(0.2, OBSERVE)
        model.predict(obs)
        print(f"paper setting, 20 % observed ({obs.n_samples} samples), medians in us")
        print("full update:")
        for name, us in full_update_stages(model, obs, repeats=3 if smoke else 2000).items():
            print(f"  {name:28s} {us:8.1f}")
        print("streaming update (kernel times are means per update, resets included):")
        for name, us in streaming_stages(model, obs, passes=1 if smoke else 30).items():
            print(f"  {name:28s} {us:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
