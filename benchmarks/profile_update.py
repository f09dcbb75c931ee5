"""Where the time of an update goes: stage timers inside back-to-back updates (paper setting).

Run ``taskset -c 0 python benchmarks/profile_update.py`` (``--smoke``: 2 tasks of 4 demos, a few
calls, seconds: what the test suite runs). A full update is timed stage by stage through the calls
that :meth:`Predictor.predict <ipromp_pin.promp.predictor.Predictor.predict>` makes, with every
feature of the default model (encode, window summary, basis statistics, the likelihood of every
(task, candidate) pair, the posteriors with the recognition head, the conditioning, the hand-over
regression's observation and read-out update, the orientation estimate's when the model has one);
the staged calls are checked to give :meth:`IProMP.predict`'s prediction. A streaming update is
split into its compiled kernels (each call timed) and the rest (Python). Medians in [us]; the stages
of a full update add up to slightly less than a full update, which has one more level of calls.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from inference import OBSERVE, split, stream_update_times, warm_up
from threadpoolctl import threadpool_limits

import ipromp_pin.promp.compiled as compiled
from ipromp_pin import IProMP
from ipromp_pin.promp.window import WindowSummary
from ipromp_pin.readers.synthetic import make_synthetic_dataset

STREAM_KERNELS = ("stream_sample", "sherman_morrison", "stream_group", "finish_soa", "recognition")


def full_update_stages(model: IProMP, obs, repeats: int = 2000) -> dict[str, float]:
    """Median time in [us] of each stage of :meth:`Predictor.predict` on ``obs`` (the calls it makes,
    in its order: with a recognition head the window summary and the head's task posterior, with a
    hand-over regression and an orientation estimate their observations and read-out updates)."""
    predictor = model.predictor_
    fm = predictor.fitted
    engine = predictor.engine
    conditioner = predictor.conditioner
    n_obs = fm.layout.n_obs_dims
    need_window = fm.head is not None or fm.handover is not None
    clock = time.perf_counter
    names = [
        "encode (input checks, scaling)",
        "window summary",
        "basis statistics",
        "pair likelihoods",
        "posteriors + head",
        "conditioning",
        "hand-over observation",
        "orientation observation",
        "total",
    ]
    rows = []
    for _ in range(repeats):
        t0 = clock()
        parts, t_last = predictor.encode(obs)
        t1 = clock()
        window = WindowSummary.from_parts(parts, n_obs) if need_window else None
        t2 = clock()
        stats = [engine.part_stats(p) for p in parts]
        t3 = clock()
        loglik = engine.log_likelihood(stats, t_last)
        t4 = clock()
        rec = predictor.recognition_from_loglik(loglik, t_last, window)
        t5 = clock()
        pred = conditioner.condition(rec, parts)
        t6 = clock()
        k = fm.tasks.index(pred.task)
        if fm.handover is not None:
            assert window is not None
            fraction = t_last / (float(pred.alpha[k]) * fm.duration_nominal_s)
            pred = conditioner.observe_handover(pred, *fm.handover.observation(k, window, fraction))
        t7 = clock()
        if fm.orientation is not None:
            observation = fm.orientation.observation(k, pred.q_mean[-1], pred.q_cov[-1])
            pred = conditioner.observe_handover(pred, *observation)
        t8 = clock()
        rows.append([t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t6 - t5, t7 - t6, t8 - t7, t8 - t0])
    med = np.median(np.array(rows), axis=0) * 1e6
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
    # the streams created below call the timed kernels
    compiled._state["modules"][(compiled.INFERENCE, "numba")] = timed
    try:
        updates = stream_update_times(model, obs, passes)
    finally:
        compiled._state["modules"][(compiled.INFERENCE, "numba")] = kernels
        compiled.set_kernel_backend(previous)
    n = len(updates) + 2 * passes  # every update calls the kernels, the first two included
    out = {"update (median)": float(np.median(updates)) * 1e6}
    for name, ts in timed.times.items():
        out[f"{name} (per update)"] = float(np.sum(ts)) / n * 1e6
    return out


def pred_of_stages(model: IProMP, obs):
    """The prediction the staged calls of :func:`full_update_stages` give (they must be the real path)."""
    predictor = model.predictor_
    fm = predictor.fitted
    parts, t_last = predictor.encode(obs)
    window = WindowSummary.from_parts(parts, fm.layout.n_obs_dims)
    loglik = predictor.engine.log_likelihood([predictor.engine.part_stats(p) for p in parts], t_last)
    rec = predictor.recognition_from_loglik(loglik, t_last, window)
    pred = predictor.conditioner.condition(rec, parts)
    k = fm.tasks.index(pred.task)
    if fm.handover is not None:
        fraction = t_last / (float(pred.alpha[k]) * fm.duration_nominal_s)
        pred = predictor.conditioner.observe_handover(pred, *fm.handover.observation(k, window, fraction))
    if fm.orientation is not None:
        observation = fm.orientation.observation(k, pred.q_mean[-1], pred.q_cov[-1])
        pred = predictor.conditioner.observe_handover(pred, *observation)
    return pred


def main(argv: list[str] | None = None) -> int:
    smoke = "--smoke" in (sys.argv[1:] if argv is None else argv)  # 2 tasks of 4 demos, few calls
    with threadpool_limits(1):
        if not smoke:
            warm_up()
        n_tasks, n_train = (2, 4) if smoke else (3, 20)
        train, test = split(make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 2, seed=1), n_train)
        settings = {"coupling": "all"} if smoke else {}  # smoke: every current feature, no coupling CV
        model = IProMP(OBSERVE, noise=10.0, blas_threads=None, **settings).fit(train)
        obs = test[model.tasks_[0]][0].head(0.2, OBSERVE)
        full = model.predict(obs)
        assert np.allclose(pred_of_stages(model, obs).q_mean, full.q_mean, rtol=1e-12, atol=1e-12)
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
