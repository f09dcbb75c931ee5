"""Benchmark: retargeting through the gripper (issue 37's target: at most 2 ms added to a one-shot plan
and 1 ms to a re-plan, one core), the compiled inverse kinematics against Pinocchio's solver.

A model is trained on the built-in synthetic demos (seed 0; Baxter's left arm) and predicts held-out
synthetic demos (seed 1). For each arm:

* **one-shot**: :func:`~ipromp_pin.planning.transfer.retarget_prediction` of the prediction from 20 %
  of each demo (its mean path and the plan's 16 sampled paths), what ``stage_ms.retarget`` of a plan
  times; also compiled with the choice of the hand-over configuration a plan makes
  (:func:`~ipromp_pin.planning.transfer.kindest_to_human`, against the assumed human: every seed's
  solution, the paths back from the distinct ones, their separation from the body);
* **re-plan**: :class:`~ipromp_pin.planning.transfer.ReplanTransfer` over the re-plans a closed loop
  makes as the observation grows (the reference motions predicted from 10 %, 12 %, ... 60 % of the
  demo; the first from the arm's start configuration, every later one from the previous re-plan's
  solution), what ``stage_ms.arm_transfer`` of a replay times.

Both versions (the kernel switch's ``"ik"`` set: ``numba``, and ``numpy``, which is Pinocchio's
solver) get the same inputs, called alternately in one process (one-shot: call by call; re-plan:
sequence by sequence, as each re-plan starts from the previous one); the medians of the wall time and
of the thread's CPU time (which a shared machine stretches less: a call of a few ms is often
preempted), their ratios and the largest difference of the results are printed. The compiled
kernels' first call in the process (loading them from numba's cache, or compiling them) is reported
apart.

    taskset -c 0 python benchmarks/retarget.py [--arms panda,ur5,xarm7,kinova_jaco2] [--demos 3]
        [--repeats 5]

``--smoke``: the Panda, a small model, one demo, one repeat (seconds).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits

from ipromp_pin.motion.retarget import ReferenceMotion
from ipromp_pin.planning.one_shot import N_UNCERTAINTY_SAMPLES
from ipromp_pin.planning.transfer import N_GRID, ReplanTransfer, kindest_to_human, retarget_prediction
from ipromp_pin.promp import IProMP, Prediction
from ipromp_pin.promp.compiled import use_kernels
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.ik_warmup import compile_kernels
from ipromp_pin.safety import CheckContext, CheckSuite

ARMS = ("panda", "ur5", "xarm7", "kinova_jaco2")
VERSIONS = (("Pinocchio", "numpy"), ("compiled", "numba"))
REPLAN_RATIOS = np.round(np.arange(0.10, 0.601, 0.02), 2)


def predictions(args: argparse.Namespace) -> list[tuple[Prediction, list[Prediction], np.ndarray]]:
    """Per held-out demo: the one-shot prediction (20 %), the re-plans' predictions, the demo's robot
    start configuration (n_source,) [rad]."""
    small = {"n_basis": 15} if args.smoke else {"n_basis": 31}
    train = make_synthetic_dataset(n_tasks=3, n_demos=5 if args.smoke else 10, seed=0)
    model = IProMP(observe=["orientation", "emg"], head=False, handover=False, coupling="all", **small)
    model.fit(train)
    out = []
    for demo in make_synthetic_dataset(n_tasks=3, n_demos=2, seed=1).all_demos()[::2][: args.demos]:
        one = model.predict(demo.head(0.2, groups=model.observe))
        ratios = REPLAN_RATIOS[::5] if args.smoke else REPLAN_RATIOS
        replans = [model.predict(demo.head(float(r), groups=model.observe)) for r in ratios]
        assert isinstance(one, Prediction) and all(isinstance(p, Prediction) for p in replans)
        out.append((one, replans, demo.groups["robot"][0]))  # type: ignore[arg-type]
    return out


def one_shot(arm: str, preds: list, repeats: int) -> tuple[dict[str, list[float]], float]:
    """Times [ms] per version, and the largest joint difference [rad] between the versions."""
    baxter, robot = load_robot("baxter_left"), load_robot(arm)
    times: dict[str, list[float]] = {k: [] for name, _ in VERSIONS for k in (name, name + " cpu")}
    diff = 0.0
    for _ in range(repeats):
        for one, _replans, _start in preds:
            samples = one.sample_q(N_UNCERTAINTY_SAMPLES, np.random.default_rng(0))
            results = []
            for name, backend in VERSIONS:
                with use_kernels(backend):
                    t0, c0 = time.perf_counter(), time.thread_time()
                    q, moved, _ = retarget_prediction(baxter, robot, one.q_mean, samples)
                    times[name].append((time.perf_counter() - t0) * 1e3)
                    times[name + " cpu"].append((time.thread_time() - c0) * 1e3)
                results.append((q, moved))
            diff = max(diff, float(np.abs(results[0][0] - results[1][0]).max()))
            diff = max(diff, float(np.abs(results[0][1] - results[1][1]).max()))
    return times, diff


def one_shot_choosing(arm: str, preds: list, repeats: int) -> list[float]:
    """CPU times [ms] of the compiled one-shot retargeting that chooses the hand-over configuration
    (the plan's own call: the preference built per plan, the separation analyser kept)."""
    baxter, robot = load_robot("baxter_left"), load_robot(arm)
    suite = CheckSuite.build(robot)
    cpu: list[float] = []
    with use_kernels("numba"):
        for _ in range(repeats):
            for one, _replans, _start in preds:
                samples = one.sample_q(N_UNCERTAINTY_SAMPLES, np.random.default_rng(0))
                along = np.linspace(0.2 * one.duration_s, one.duration_s, one.q_mean.shape[0])
                c0 = time.thread_time()
                prefer = kindest_to_human(suite, CheckContext(), along)
                retarget_prediction(baxter, robot, one.q_mean, samples, prefer=prefer)
                cpu.append((time.thread_time() - c0) * 1e3)
    return cpu


def replan(arm: str, preds: list, repeats: int) -> tuple[dict[str, list[float]], float, float]:
    """Times [ms] per version, the largest difference of the fitted weights [rad] and of the path
    residual [mm] between the versions."""
    baxter, robot = load_robot("baxter_left"), load_robot(arm)
    times: dict[str, list[float]] = {k: [] for name, _ in VERSIONS for k in (name, name + " cpu")}
    d_w = d_mm = 0.0
    for _ in range(repeats):
        for _one, replans, start in preds:
            runs = []
            for name, backend in VERSIONS:
                with use_kernels(backend):
                    transfer = ReplanTransfer(baxter, robot)
                    q_now = transfer.start(start)
                    run = []
                    for p in replans:
                        ref = ReferenceMotion.from_prediction(p)
                        t0, c0 = time.perf_counter(), time.thread_time()
                        moved, report = transfer.reference(ref, q_now, 0.0)
                        times[name].append((time.perf_counter() - t0) * 1e3)
                        times[name + " cpu"].append((time.thread_time() - c0) * 1e3)
                        run.append((None if moved is None else moved.weights, report.max_path_residual_mm))
                runs.append(run)
            for (wa, ma), (wb, mb) in zip(runs[0], runs[1], strict=True):
                if wa is not None and wb is not None:
                    d_w = max(d_w, float(np.abs(wa - wb).max()))
                d_mm = max(d_mm, abs(ma - mb))
    return times, d_w, d_mm


def first_call_s() -> float:
    """Seconds of the compiled kernels' first calls in this process (loaded from numba's cache, or
    compiled when it lacks them): the warm-up's calls, every kernel with its signature."""
    t0 = time.perf_counter()
    compile_kernels()
    return time.perf_counter() - t0


def report(label: str, times: dict[str, list[float]]) -> str:
    ref, new = (float(np.median(times[name])) for name, _ in VERSIONS)
    ref_cpu, new_cpu = (float(np.median(times[name + " cpu"])) for name, _ in VERSIONS)
    return (
        f"{label}: Pinocchio median {ref:.3f} ms, compiled median {new:.3f} ms: {ref / new:.1f}x faster; "
        f"CPU time {ref_cpu:.3f} ms, {new_cpu:.3f} ms: {ref_cpu / new_cpu:.1f}x "
        f"({len(times['compiled'])} calls each)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--arms", default=",".join(ARMS), help="comma-separated robots (default: every placed arm)"
    )
    parser.add_argument("--demos", type=int, default=3, help="held-out demos (one per task, up to 3)")
    parser.add_argument("--repeats", type=int, default=5, help="repeats of every call")
    parser.add_argument("--smoke", action="store_true", help="the Panda, a small model, one demo (seconds)")
    args = parser.parse_args()
    arms = ["panda"] if args.smoke else [a for a in args.arms.split(",") if a]
    if args.smoke:
        args.demos, args.repeats = 1, 1
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    with threadpool_limits(1):
        machine = platform.processor() or platform.machine()
        print(f"machine: {machine}, Python {platform.python_version()}, one CPU")
        print(f"compiled kernels' first call in this process: {first_call_s():.2f} s")
        preds = predictions(args)
        n_path = preds[0][0].q_mean.shape[0]
        print(
            f"{len(preds)} held-out demos; one-shot: a {n_path}-sample mean path and {N_UNCERTAINTY_SAMPLES} "
            f"sampled paths; re-plan: {len(preds[0][1])} re-plans per demo, {N_GRID} "
            "phases each"
        )
        for arm in arms:
            times, diff = one_shot(arm, preds, args.repeats)
            print(f"{arm} {report('one-shot retarget', times)}; largest joint difference {diff:.1e} rad")
            cpu = one_shot_choosing(arm, preds, args.repeats)
            print(
                f"{arm} one-shot retarget choosing the hand-over configuration: compiled CPU time median "
                f"{np.median(cpu):.3f} ms ({len(cpu)} calls)"
            )
            times, d_w, d_mm = replan(arm, preds, args.repeats)
            print(
                f"{arm} {report('re-plan retarget', times)}; largest difference: weights {d_w:.1e} rad, "
                f"path residual {d_mm:.1e} mm"
            )


if __name__ == "__main__":
    main()
