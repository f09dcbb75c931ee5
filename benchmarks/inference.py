"""Inference benchmark: training, full update, streaming update, direct reference, scaling, phase accuracy.

Run ``python benchmarks/inference.py`` (full, several minutes), ``--quick`` (about a minute) or
``--smoke`` (tiny settings, seconds: what the test suite runs so that the script cannot silently
rot); ``--json FILE`` writes the medians in seconds. Everything runs on ONE core
(process pinned to one CPU when possible, BLAS limited to one thread).

Settings. "paper": 3 tasks, 4 orientation + 8 EMG observed dims, 7 robot joints, 31 basis
functions, 20 training demos per task, 50 Hz synthetic hand-overs of 2.5-4.2 s
(:func:`ipromp_pin.readers.synthetic.make_synthetic_dataset`), observed ratios 0.1 and 0.2, the model's
default ``coupling="auto"`` (on these demos it couples orientation alone to the robot, so the EMG
forms a second independent block: ranks 19 + 19). "paper1blk" is the same with ``coupling="all"``
(one block of rank 19, the textbook model). Scaled settings change one factor at a time: 10 / 30
tasks, 30 observed dims (extra channels mixed from the measured ones), 61 basis functions, 100
demos per task.

Inference runs compiled numba kernels (:mod:`ipromp_pin.promp._kernels`): every setting is warmed up
before timing; the first-call time and the cold compile time (fresh process, empty numba
cache) are reported separately.

Medians: the paper settings time 300 full updates per ratio and about 1000 streaming updates (30
passes over the 37 samples of 20 % of a demo) in 6 rounds spread over their run (each round visits
every quantity), the scaled settings 10 calls in one round (``--quick``: the paper settings 100 full
updates per ratio, about a second, in one round; 5 had made its medians those of a cold burst).

"full update" = :meth:`IProMP.predict` (phase posterior over every candidate of every task,
task posterior, conditioned prediction of the winner); "streaming update" = one
:meth:`StreamingEstimator.update` with a new sample; "direct" =
:func:`ipromp_pin.promp.direct_predict` (dense block-diagonal Phi per candidate, full
covariance ``Phi Sigma Phi^T + R`` via Cholesky, dense conditioning).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import tracemalloc
from collections.abc import Callable

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from ipromp_pin.data import Dataset, Demo
from ipromp_pin.promp import IProMP, direct_predict
from ipromp_pin.promp.reference import parabola_vertex
from ipromp_pin.readers.synthetic import make_synthetic_dataset

OBSERVE = ["orientation", "emg"]


def wall_times(fn: Callable[[], object], repeats: int) -> list[float]:
    """Wall times of ``repeats`` calls of ``fn`` in [s]."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def median_time(fn: Callable[[], object], repeats: int, warmup: int = 1) -> float:
    """Median wall time of ``fn`` in [s]."""
    for _ in range(warmup):
        fn()
    return float(np.median(wall_times(fn, repeats)))


def with_extra_dims(ds: Dataset, n_extra: int, seed: int = 0) -> Dataset:
    """Add a group "extra" of ``n_extra`` channels: random mixes of the orientation and EMG plus noise."""
    rng = np.random.default_rng(seed)
    mix = rng.normal(size=(12, n_extra))
    demos = {}
    for task, ds_demos in ds.demos.items():
        out = []
        for d in ds_demos:
            base = np.concatenate([d.groups["orientation"], d.groups["emg"] / 100.0], axis=1)
            extra = base @ mix + rng.normal(0, 0.02, (d.n_samples, n_extra))
            groups = {**d.groups, "extra": extra}
            names = {**d.channel_names, "extra": tuple(f"x{i}" for i in range(n_extra))}
            out.append(
                Demo(
                    d.task,
                    d.name,
                    d.source,
                    d.t,
                    groups,
                    names,
                    dict(d.missing),
                    dict(d.extras),
                    d.duration_s,
                )
            )
        demos[task] = out
    return Dataset(ds.root + "+extra", demos)


def split(ds: Dataset, n_train: int) -> tuple[Dataset, dict[str, list[Demo]]]:
    return (
        Dataset(ds.root, {t: d[:n_train] for t, d in ds.demos.items()}),
        {t: d[n_train:] for t, d in ds.demos.items()},
    )


def stream_update_times(model: IProMP, obs: Demo, passes: int = 30) -> list[float]:
    """Times in [s] of the streaming updates of ``passes`` streams of the samples of ``obs`` (each
    stream's first two left out)."""
    times = []
    for _ in range(passes):
        with model.stream() as stream:
            for j in range(obs.n_samples):
                sample = {g: obs.groups[g][j] for g in model.observe}
                t0 = time.perf_counter()
                stream.update(obs.t[j], sample)
                if j >= 2:
                    times.append(time.perf_counter() - t0)
    return times


def run_setting(
    name: str,
    n_tasks: int = 3,
    n_demos: int = 20,
    n_basis: int = 31,
    n_extra: int = 0,
    n_alpha: int | None = None,
    repeats: int = 30,
    ratios: tuple[float, ...] = (0.1, 0.2),
    stream: bool = True,
    coupling: str = "auto",
    rounds: int = 1,
    **model_kw: object,
) -> dict[str, float]:
    """Train on one setting and time the inference; returns medians in [s] and sizes.

    The timed calls are split into ``rounds`` rounds that visit every quantity in turn (full
    updates at each ratio, recognition, streaming), so that each median pools calls made at
    ``rounds`` moments of the run rather than in one burst (this VM's speed drifts over seconds).
    """
    ds = make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_demos + 2, seed=1)
    observe = list(OBSERVE)
    if n_extra:
        ds = with_extra_dims(ds, n_extra)
        observe.append("extra")
    train, test = split(ds, n_demos)
    # the whole benchmark runs with BLAS limited to one thread, so the model's own per-call
    # limit (blas_threads, about 15-45 us a call) is switched off
    kw = dict(model_kw) if n_alpha is None else {**model_kw, "n_alpha": n_alpha}
    model = IProMP(observe, n_basis=n_basis, noise=10.0, blas_threads=None, coupling=coupling, **kw)
    tracemalloc.start()
    t0 = time.perf_counter()
    model.fit(train)
    train_s = (time.perf_counter() - t0) / n_tasks
    _, peak_fit = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    demo = test[model.tasks_[0]][0]
    out: dict[str, float] = {"train_per_task_s": train_s, "peak_fit_mb": peak_fit / 1e6}
    # warm-up: the first inference of a process loads (or compiles) the numba kernels; never timed below
    t0 = time.perf_counter()
    model.predict(demo.head(ratios[0], observe))
    out["first_call_s"] = time.perf_counter() - t0
    out["n_candidates"] = float(model.models_[model.tasks_[0]].alpha_grid.size)
    out["n_obs_dims"] = float(model.n_obs_dims_)
    out["rank"] = float(model.predictor_.engine.rank)
    observations = {}
    for ratio in ratios:
        obs = demo.head(ratio, observe)
        tracemalloc.start()
        model.predict(obs)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        key = f"r{int(round(ratio * 100)):02d}"
        observations[key] = obs
        model.recognise(obs)
        out[f"n_samples_{key}"] = float(obs.n_samples)
        out[f"peak_predict_{key}_mb"] = peak / 1e6
    times: dict[str, list[float]] = {}
    per_round = -(-repeats // rounds)
    passes = -(-30 // rounds)
    for _ in range(rounds):
        for key, obs in observations.items():
            times.setdefault(f"full_update_{key}_s", []).extend(
                wall_times(lambda obs=obs: model.predict(obs), per_round)
            )
            times.setdefault(f"recognise_{key}_s", []).extend(
                wall_times(lambda obs=obs: model.recognise(obs), per_round)
            )
        if stream:
            times.setdefault("streaming_update_s", []).extend(
                stream_update_times(model, demo.head(0.2, observe), passes)
            )
    out.update({k: float(np.median(v)) for k, v in times.items()})
    out["_model"] = model  # type: ignore[assignment]
    out["_test"] = test  # type: ignore[assignment]
    return out


def warm_up() -> None:
    """Load (or compile) every numba kernel once, so that no timing below includes it."""
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=2)
    model = IProMP(OBSERVE, n_basis=11, noise=1.0).fit(ds)  # coupling CV: conditioning kernels
    demo = ds.demos[model.tasks_[0]][0].head(0.3, OBSERVE)
    model.predict(demo)
    with model.stream() as stream:
        for j in range(demo.n_samples):
            stream.update(demo.t[j], {g: demo.groups[g][j] for g in OBSERVE})


def cold_compile_time() -> float:
    """First-inference time in [s] of a fresh process with an empty numba cache (full JIT compilation)."""
    import subprocess
    import tempfile

    code = (
        "import time\n"
        "from ipromp_pin import IProMP\n"
        "from ipromp_pin.readers.synthetic import make_synthetic_dataset\n"
        "ds = make_synthetic_dataset(n_tasks=2, n_demos=4, seed=0)\n"
        "m = IProMP(['orientation', 'emg'], noise=1.0).fit(ds)\n"
        "d = ds.demos[m.tasks_[0]][0].head(0.2, m.observe)\n"
        "t0 = time.perf_counter(); m.predict(d); s = m.stream()\n"
        "[s.update(d.t[j], {g: d.groups[g][j] for g in m.observe}) for j in range(3)]\n"
        "print(time.perf_counter() - t0)\n"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cmd = [sys.executable, "-c", code]
        res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return float(res.stdout.strip().splitlines()[-1])


def direct_time(model: IProMP, obs: Demo, repeats: int) -> tuple[float, float]:
    """Median direct time in [s] and the largest relative difference fast vs direct."""
    fast = model.predict(obs)
    ref = direct_predict(model.predictor_, obs)
    diff = max(
        float(
            np.max(np.abs(getattr(fast, f) - getattr(ref, f))) / max(np.max(np.abs(getattr(ref, f))), 1e-300)
        )
        for f in ("posterior", "alpha", "q_mean", "q_cov")
    )
    return median_time(lambda: direct_predict(model.predictor_, obs), repeats, warmup=0), diff


def phase_accuracy(model: IProMP, test: dict[str, list[Demo]], ratios=(0.1, 0.2)) -> list[str]:
    """Phase and task accuracy on held-out synthetic demos with known alpha = T / T_norm."""
    lines = []
    for ratio in ratios:
        err, prior, hits, cond, base = [], [], [], [], []
        for task, demos in test.items():
            for d in demos:
                p = model.predict(d.head(ratio, model.observe))
                k = p.tasks.index(task)
                true = d.duration_s / model.duration_nominal_s_
                err.append(abs(p.alpha[k] - true) / true)
                prior.append(abs(model.models_[task].alpha_mu - true) / true)
                hits.append(p.task == task)
                z = p.t / p.duration_s
                q = np.stack([np.interp(z, d.t / d.t[-1], d.groups["robot"][:, j]) for j in range(7)], axis=1)
                cond.append(np.sqrt(np.mean((p.q_mean - q) ** 2)))
                base.append(np.sqrt(np.mean((p.q_prior_mean - q) ** 2)))
        lines.append(
            f"  ratio {ratio:.1f}: phase error |alpha-true|/true mean {np.mean(err):.3f}"
            f" median {np.median(err):.3f}"
            f" (prior mean alone: mean {np.mean(prior):.3f} median {np.median(prior):.3f});"
            f" task accuracy {np.mean(hits):.2f}; robot RMSE conditioned {np.mean(cond):.4f} rad,"
            f" unconditioned prior {np.mean(base):.4f} rad"
        )
    return lines


def phase_search_accuracy(ratios=(0.1, 0.2, 0.3)) -> list[str]:
    """The continuous phase estimate vs a dense grid: distance to the exact MAP and error vs the true alpha.

    Paper setting (20 training and 20 held-out demos per task, nu = 10). The exact continuous MAP is
    the default estimate on a 1000-candidate grid; the default model (``n_alpha=20``, interpolated
    between candidates) is compared with a 50-candidate grid refined by a parabola through the
    best candidate and its neighbours (the estimator the interpolation replaced).
    """
    ds = make_synthetic_dataset(n_tasks=3, n_demos=40, seed=1)
    train, test = split(ds, 20)
    models = {
        "exact": IProMP(OBSERVE, n_alpha=1000, noise=10.0).fit(train),
        "default": IProMP(OBSERVE, noise=10.0).fit(train),
        "grid50": IProMP(OBSERVE, n_alpha=50, noise=10.0).fit(train),
    }

    def parabola(grid: np.ndarray, lp: np.ndarray) -> float:
        i = int(np.argmax(lp))
        return (
            float(grid[i])
            if i in (0, grid.size - 1)
            else parabola_vertex(*grid[i - 1 : i + 2], *lp[i - 1 : i + 2])
        )

    lines = []
    for ratio in ratios:
        est: dict[str, list[float]] = {"exact": [], "default": [], "grid50": []}
        true = []
        for task, demos in test.items():
            for d in demos:
                obs = d.head(ratio, OBSERVE)
                true.append(d.duration_s / models["exact"].duration_nominal_s_)
                for name, m in models.items():
                    p = m.recognise(obs)
                    k = p.tasks.index(task)
                    a = p.alpha[k] if name != "grid50" else parabola(p.phase_grid[k], p.phase_log_post[k])
                    est[name].append(float(a))
        exact, tr = np.array(est["exact"]), np.array(true)
        parts = []
        for name, label in (
            ("default", f"{models['default'].n_alpha} cands + interpolation"),
            ("grid50", "50 cands + parabola"),
        ):
            a = np.array(est[name])
            dev = np.abs(a - exact) / exact
            err = np.abs(a - tr) / tr
            parts.append(
                f"{label}: |alpha - exact MAP| / alpha median {np.median(dev):.1e} max {np.max(dev):.1e},"
                f" error vs true mean {np.mean(err):.5f}"
            )
        lines.append(f"  ratio {ratio:.1f}: " + "; ".join(parts))
    return lines


def machine_info() -> list[str]:
    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    blas = ", ".join(f"{i['internal_api']} {i.get('version')}" for i in threadpool_info())
    return [
        f"machine: {cpu}, {os.cpu_count()} logical CPUs, pinned to CPU {sorted(os.sched_getaffinity(0))}"
        if hasattr(os, "sched_getaffinity")
        else f"machine: {cpu}",
        f"python {platform.python_version()}, numpy {np.__version__}, BLAS {blas} (limited to 1 thread)",
    ]


SMOKE_MODEL = {"head": False, "handover": False}
"""Model settings of ``--smoke`` (no recognition head or hand-over regression to fit: seconds)."""

SCALED = [
    ("paper1blk", {"coupling": "all"}),
    ("10tasks", {"n_tasks": 10}),
    ("30tasks", {"n_tasks": 30}),
    ("dims30", {"n_extra": 18}),
    ("basis61", {"n_basis": 61}),
    ("demos100", {"n_demos": 100}),
    ("alpha50", {"n_alpha": 50}),
]
"""Scaled settings (one factor changed from the paper setting); the full run adds 100 and 200
candidates."""


def measure(mode: str) -> dict:
    """Every measurement of one run; ``mode`` is ``"full"``, ``"quick"`` or ``"smoke"`` (2 tasks of 4
    demos, a few calls, no cold compile, no phase search, only two scaled settings: seconds)."""
    quick, smoke = mode == "quick", mode == "smoke"
    reps = 5 if quick else 30
    # the paper settings' full updates take about a millisecond: many repeats make their medians
    # robust to this VM's bursts of interference
    paper_reps = 2 if smoke else 100 if quick else 300
    paper_rounds = 6 if mode == "full" else 1
    tiny = {"n_tasks": 2, "n_demos": 4, **SMOKE_MODEL} if smoke else {}
    out: dict = {"mode": mode}
    print("\n".join(machine_info()))
    out["cold"] = cold_compile_time() if mode == "full" else float("nan")
    if not smoke:
        warm_up()
    paper = run_setting("paper", repeats=paper_reps, rounds=paper_rounds, **tiny)
    model, test = paper.pop("_model"), paper.pop("_test")
    settings = {"paper": paper}
    scaled = list(SCALED)
    if mode == "full":
        scaled += [("alpha100", {"n_alpha": 100}), ("alpha200", {"n_alpha": 200})]
    if smoke:
        scaled = [(name, kw) for name, kw in scaled if name in ("paper1blk", "dims30")]
    models = {"paper": model}
    for name, kw in scaled:
        if name == "paper1blk":
            r = run_setting(name, repeats=paper_reps, rounds=paper_rounds, **{**tiny, **kw})
        else:
            r = run_setting(name, repeats=1 if smoke else max(3, reps // 3), **{**tiny, **kw})
        models[name] = r.pop("_model")
        r.pop("_test")
        settings[name] = r
    # direct reference, same run
    demo = test[model.tasks_[0]][0]
    direct = {}
    for ratio in (0.1, 0.2):
        if mode != "full" and ratio == 0.2:
            continue
        obs = demo.head(ratio, model.observe)
        direct[ratio] = direct_time(model, obs, 3 if mode == "full" else 1)
    per_task = direct[0.1][0] / len(model.tasks_)  # direct cost is linear in the number of tasks
    direct_scaled = {}
    for name in [n for n in ("10tasks", "30tasks") if n in models]:
        m = models[name]
        if quick:
            direct_scaled[name] = (per_task * len(m.tasks_), float("nan"), True)
        else:
            t, diff = direct_time(m, demo.head(0.1, m.observe), 1)
            direct_scaled[name] = (t, diff, False)
    n_tasks, n_train = (2, 4) if smoke else (3, 20)
    auto = IProMP(OBSERVE, **(SMOKE_MODEL if smoke else {}))
    train_auto, _ = split(make_synthetic_dataset(n_tasks=n_tasks, n_demos=n_train + 2, seed=1), n_train)
    t0 = time.perf_counter()
    auto.fit(train_auto)
    out["train_auto_s"] = (time.perf_counter() - t0) / n_tasks
    out["accuracy"] = phase_accuracy(auto, test)
    out["search"] = ["  not measured (--smoke)"] if smoke else phase_search_accuracy()
    out.update(model=model, paper=paper, settings=settings, direct=direct, direct_scaled=direct_scaled)
    out["auto"] = auto
    return out


def ms(x: float) -> str:
    return f"{x * 1e3:9.3f}"


def print_times(m: dict) -> None:
    """The table of medians per setting and the direct reference."""
    settings, paper = m["settings"], m["paper"]
    print("\nmedian times on one core (ms); r10/r20 = observed ratio 0.1/0.2")
    head = (
        f"{'setting':10s} {'cands':>5s} {'dims':>4s} {'rank':>4s} {'train/task':>10s} {'full r10':>9s} "
        f"{'full r20':>9s} {'recog r20':>9s} {'stream':>9s} {'n r10/r20':>9s} {'peak fit MB':>11s} "
        f"{'peak pred MB':>12s}"
    )
    print(head)
    for name, r in settings.items():
        print(
            f"{name:10s} {int(r['n_candidates']):5d} {int(r['n_obs_dims']):4d} {int(r['rank']):4d} "
            f"{ms(r['train_per_task_s']):>10s} {ms(r['full_update_r10_s'])} {ms(r['full_update_r20_s'])} "
            f"{ms(r['recognise_r20_s'])} {ms(r['streaming_update_s'])} "
            f"{int(r['n_samples_r10']):4d}/{int(r['n_samples_r20']):<4d} {r['peak_fit_mb']:11.1f} "
            f"{r['peak_predict_r20_mb']:12.2f}"
        )
    print("\ndirect (textbook) reference, same run:")
    for ratio, (t, diff) in m["direct"].items():
        key = f"full_update_r{int(round(ratio * 100)):02d}_s"
        print(
            f"  paper ratio {ratio:.1f}: direct {t * 1e3:.1f} ms, fast {paper[key] * 1e3:.3f} ms, "
            f"speed-up {t / paper[key]:.0f}x, max relative difference {diff:.1e}"
        )
    for name, (t, diff, extrapolated) in m["direct_scaled"].items():
        note = (
            " (extrapolated: paper per-task direct time x tasks)"
            if extrapolated
            else f", max rel diff {diff:.1e}"
        )
        fast = settings[name]["full_update_r10_s"]
        print(f"  {name} ratio 0.1: direct {t * 1e3:.1f} ms, speed-up {t / fast:.0f}x{note}")


def print_growth(m: dict) -> None:
    """How the full update grows with each factor (the settings this run measured)."""
    settings, paper = m["settings"], m["paper"]

    def r20(name: str) -> str:
        return ms(settings[name]["full_update_r20_s"]).strip()

    print("\ngrowth (full update, ratio 0.2, ms):")
    tasks = [k for k in ("paper", "10tasks", "30tasks") if k in settings]
    print(
        "  tasks "
        + "/".join(str(len(m["model"].tasks_)) if k == "paper" else k[:2] for k in tasks)
        + ": "
        + " / ".join(r20(k) for k in tasks)
    )
    alphas = [k for k in ("paper", "alpha50", "alpha100", "alpha200") if k in settings]
    print(
        "  candidates "
        + "/".join(str(int(settings[k]["n_candidates"])) for k in alphas)
        + ": "
        + " / ".join(r20(k) for k in alphas)
    )
    print(
        f"  observed samples {int(paper['n_samples_r10'])}/{int(paper['n_samples_r20'])}: "
        f"{ms(paper['full_update_r10_s']).strip()} / {r20('paper')}"
    )
    for name, label in (("dims30", "observed dims 12/30"), ("basis61", "basis 31/61")):
        if name in settings:
            print(f"  {label}: {r20('paper')} / {r20(name)}")
    if "demos100" in settings:
        print(
            f"  demos 20/100 (rank {int(paper['rank'])}/{int(settings['demos100']['rank'])}): "
            f"{r20('paper')} / {r20('demos100')}"
        )


def print_accuracy(m: dict) -> None:
    """Kernel load/compile times, the noise chosen by cross-validation and the phase/task accuracy."""
    paper, model, auto = m["paper"], m["model"], m["auto"]
    print(
        f"\nnumba kernels: first inference of this process {paper['first_call_s']:.2f} s (cache load or"
        f" compile); fresh process with an empty cache (full compile) "
        + (f"not measured (--{m['mode']})" if m["mode"] != "full" else f"{m['cold']:.1f} s")
    )
    print(f"basis Gram condition number (K={model.n_basis}): {model.basis_.condition_number():.3g}")
    print(
        f"noise='auto' (leave-one-out CV): chose nu = {auto.noise_ratio_:g}, "
        f"training {m['train_auto_s']:.2f} s per task "
        f"(scores: {', '.join(f'{k:g}: {v:.2f}' for k, v in auto.cv_scores_.items())})"
    )
    print("phase / task accuracy on held-out synthetic demos (paper setting, CV-chosen noise):")
    print("\n".join(m["accuracy"]))
    print("continuous phase estimate vs the exact MAP (1000 candidates), held-out synthetic demos:")
    print("\n".join(m["search"]))


def json_results(m: dict) -> dict:
    """The medians in [s] (and a few sizes) written by ``--json``."""
    results: dict = {}
    for name, r in m["settings"].items():
        suffix = "paper" if name == "paper" else name
        results[f"full_update_{suffix}_s"] = r["full_update_r20_s"]
        results[f"full_update_r10_{suffix}_s"] = r["full_update_r10_s"]
        results[f"full_update_r20_{suffix}_s"] = r["full_update_r20_s"]
        results[f"recognise_r20_{suffix}_s"] = r["recognise_r20_s"]
        results[f"streaming_update_{suffix}_s"] = r["streaming_update_s"]
        results[f"train_per_task_{suffix}_s"] = r["train_per_task_s"]
    direct = m["direct"]
    results["direct_full_update_paper_s"] = direct[0.2][0] if 0.2 in direct else direct[0.1][0]
    results["direct_full_update_r10_paper_s"] = direct[0.1][0]
    for name, (t, _, _) in m["direct_scaled"].items():
        results[f"direct_full_update_{name}_s"] = t
    results["direct_extrapolated"] = m["mode"] == "quick"
    results["train_per_task_auto_noise_paper_s"] = m["train_auto_s"]
    results["basis_condition_number"] = m["model"].basis_.condition_number()
    results["first_call_paper_s"] = m["paper"]["first_call_s"]
    results["jit_compile_cold_s"] = m["cold"]
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fast run (fewer repeats, extrapolated direct)")
    ap.add_argument("--smoke", action="store_true", help="tiny settings, a few calls: seconds (the tests)")
    ap.add_argument("--json", metavar="FILE", help="write medians in [s] to FILE")
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        try:
            os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        except OSError:
            pass
    with threadpool_limits(1):
        m = measure("smoke" if args.smoke else "quick" if args.quick else "full")
    print_times(m)
    print_growth(m)
    print_accuracy(m)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(json_results(m), fh, indent=2, sort_keys=True)
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
