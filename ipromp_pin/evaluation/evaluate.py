"""Evaluation: the paper's recognition experiment and a repeated random-split protocol.

Two protocols, both honest about what is known online (the test demo's total
duration and phase are never given to the model; it sees only the first
``obs_ratio`` of the human channels it is told to observe):

* ``paper``: per task, the first ``n_train`` demos (in the order of the
  authors' ``filename_<task>.cfg``, else the recorded order) train, the next
  ``n_test`` (10) test. Cells: (n_train, obs_ratio) in
  :data:`PAPER_GRID`, for every observed channel set.
* ``splits``: the same cells, each repeated over ``n_splits`` random
  train/test splits per task; reported as mean and standard deviation.

Besides recognition accuracy, every correctly recognised test trial measures
how well the robot's motion is predicted, next to the unconditioned task mean
(the prior), so the value of conditioning is visible:

* joint RMSE in [rad] over the unobserved part of the motion, compared in
  normalised phase (prediction and truth each over their own duration);
* the error of the final (hand-over) joint configuration, RMS over joints in
  [rad];
* the hand-over gripper position error in [cm], through forward kinematics.
"""

from __future__ import annotations

import json
import multiprocessing as mp
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np

from .. import atomic
from ..data import ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..promp import IProMP
from ..robot import ee_positions, load_robot
from ..shipped import DEFAULT_ROBOT
from .baselines import CLASSIFIERS, REGRESSORS, BaselineTrial, WindowBaselines

J = TypeVar("J")
R = TypeVar("R")

PAPER_GRID: tuple[tuple[int, float], ...] = ((20, 0.1), (15, 0.1), (10, 0.1), (10, 0.2))
"""(n_train, obs_ratio) cells of the paper's table."""

PAPER_ACCURACY: dict[tuple[int, float, str], dict[str, float]] = {
    (20, 0.1, "orientation"): {"aluminum_hold": 0.90, "spanner_handover": 0.60, "tape_hold": 0.10},
    (20, 0.1, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 1.00, "tape_hold": 0.70},
    (15, 0.1, "orientation"): {"aluminum_hold": 0.60, "spanner_handover": 0.60, "tape_hold": 0.10},
    (15, 0.1, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 0.90, "tape_hold": 0.70},
    (10, 0.1, "orientation"): {"aluminum_hold": 0.00, "spanner_handover": 0.00, "tape_hold": 0.80},
    (10, 0.1, "orientation+emg"): {"aluminum_hold": 0.50, "spanner_handover": 0.80, "tape_hold": 0.70},
    (10, 0.2, "orientation"): {"aluminum_hold": 0.30, "spanner_handover": 1.00, "tape_hold": 0.90},
    (10, 0.2, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 1.00, "tape_hold": 1.00},
}
"""Accuracies reported in the paper (Chen et al. 2017) on ``chen2017_handover``, per task."""

ProgressFn = Callable[[int, int, str], None]


@dataclass
class TrialResult:
    """Outcome of one test trial.

    Attributes:
        task: True task of the test demo.
        demo: Test demo name.
        predicted: Recognised task.
        posterior: Posterior of the true task.
        joint_rmse_rad: RMSE over joints and the unobserved phase, conditioned prediction, in [rad].
        joint_rmse_prior_rad: The same for the unconditioned task mean, in [rad].
        final_joint_error_rad: RMS over joints of the final configuration error, in [rad].
        final_joint_error_prior_rad: The same for the prior mean, in [rad].
        handover_error_cm: Gripper position error at the hand-over, in [cm] (NaN without FK).
        handover_error_prior_cm: The same for the prior mean, in [cm].
        duration_error_s: Predicted minus true duration of the motion, in [s].
        brier: Multi-class Brier score of the task posterior (sum over tasks of squared errors).
        baselines: Baseline name -> its outcome on the same window (``--baselines``,
            :mod:`ipromp_pin.evaluation.baselines`).
    """

    task: str
    demo: str
    predicted: str
    posterior: float
    joint_rmse_rad: float
    joint_rmse_prior_rad: float
    final_joint_error_rad: float
    final_joint_error_prior_rad: float
    handover_error_cm: float
    handover_error_prior_cm: float
    duration_error_s: float
    brier: float = float("nan")
    baselines: dict[str, BaselineTrial] = field(default_factory=dict)

    @property
    def correct(self) -> bool:
        """True when the task was recognised."""
        return self.predicted == self.task


@dataclass
class Cell:
    """One cell of the accuracy table: a protocol, training size, ratio, observed set and task.

    ``coupled_groups`` counts, over the cell's model fits, the observed groups each fitted model
    coupled to the robot (``"+"``-joined, ``""`` for none; see ``IProMP(coupling=...)``).
    ``log_loss`` (mean of ``-log p(true task)``, posteriors floored at :data:`PROBABILITY_FLOOR`) and
    ``brier`` (mean multi-class Brier score) say how well calibrated the task posterior is.
    ``baselines`` (``--baselines``): baseline name -> ``accuracy``, ``log_loss``, ``brier`` (and
    ``accuracy_std`` over splits) for the classifiers, the median ``handover_error_cm``,
    ``joint_rmse_rad`` and ``final_joint_error_rad`` over the trials ipromp_pin recognised for the
    regressors (the true task given to them).
    """

    protocol: str
    n_train: int
    obs_ratio: float
    observe: list[str]
    task: str
    accuracy: float
    n_test: int
    accuracy_std: float | None = None
    n_splits: int | None = None
    paper_accuracy: float | None = None
    joint_rmse_rad: float | None = None
    joint_rmse_prior_rad: float | None = None
    final_joint_error_rad: float | None = None
    final_joint_error_prior_rad: float | None = None
    handover_error_cm: float | None = None
    handover_error_prior_cm: float | None = None
    duration_error_s: float | None = None
    coupled_groups: dict[str, int] = field(default_factory=dict)
    log_loss: float | None = None
    brier: float | None = None
    baselines: dict[str, dict[str, float | None]] = field(default_factory=dict)
    trials: list[dict] = field(default_factory=list)


PROBABILITY_FLOOR = 1e-15
"""Posteriors are floored at this value in the log loss (a confident mistake costs at most 34.5)."""


def observe_key(observe: Sequence[str]) -> str:
    """Canonical text of an observed channel set, e.g. ``"orientation+emg"``."""
    return "+".join(observe)


def _median(values: Sequence[float]) -> float | None:
    arr = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    return float(np.median(arr)) if arr.size else None


def _phase_interp(t: np.ndarray, q: np.ndarray, duration_s: float, z: np.ndarray) -> np.ndarray:
    """Values of a trajectory ``q`` (N, D) sampled at ``t`` (N,) at phases ``z`` of ``duration_s``."""
    tz = z * duration_s
    return np.stack([np.interp(tz, t, q[:, j]) for j in range(q.shape[1])], axis=1)


def score_trial(
    prediction, demo: Demo, obs_ratio: float, fk: Callable[[np.ndarray], np.ndarray] | None
) -> TrialResult:
    """Measure one prediction against the full test demo.

    Args:
        prediction: The model's prediction from the observed part of ``demo``.
        demo: The full test demo (its robot group is the ground truth).
        obs_ratio: Observed fraction, in (0, 1].
        fk: Forward kinematics, joint configurations (n, 7) in [rad] -> gripper
            positions (n, 3) in [m]; ``None`` skips the Cartesian error.
    """
    truth = demo.groups[ROBOT]
    z = np.linspace(obs_ratio, 1.0, 50)
    true_z = _phase_interp(demo.t - demo.t[0], truth, demo.duration_s, z)
    pred_z = _phase_interp(prediction.t, prediction.q_mean, prediction.duration_s, z)
    prior_z = _phase_interp(prediction.t, prediction.q_prior_mean, prediction.duration_s, z)
    rmse = float(np.sqrt(np.mean((pred_z - true_z) ** 2)))
    rmse_prior = float(np.sqrt(np.mean((prior_z - true_z) ** 2)))
    q_true_end = truth[-1]
    q_pred_end = prediction.q_mean[-1]
    q_prior_end = prediction.q_prior_mean[-1]
    fin = float(np.sqrt(np.mean((q_pred_end - q_true_end) ** 2)))
    fin_prior = float(np.sqrt(np.mean((q_prior_end - q_true_end) ** 2)))
    ho = ho_prior = float("nan")
    if fk is not None:
        p = fk(np.stack([q_true_end, q_pred_end, q_prior_end]))
        ho = float(np.linalg.norm(p[1] - p[0]) * 100.0)
        ho_prior = float(np.linalg.norm(p[2] - p[0]) * 100.0)
    k_true = prediction.tasks.index(demo.task) if demo.task in prediction.tasks else None
    onehot = np.array([t == demo.task for t in prediction.tasks], dtype=float)
    return TrialResult(
        task=demo.task,
        demo=demo.name,
        predicted=prediction.task,
        posterior=float(prediction.posterior[k_true]) if k_true is not None else 0.0,
        joint_rmse_rad=rmse,
        joint_rmse_prior_rad=rmse_prior,
        final_joint_error_rad=fin,
        final_joint_error_prior_rad=fin_prior,
        handover_error_cm=ho,
        handover_error_prior_cm=ho_prior,
        duration_error_s=float(prediction.duration_s - demo.duration_s),
        brier=float(np.sum((np.asarray(prediction.posterior) - onehot) ** 2)),
    )


def summarise(trials: Sequence[TrialResult]) -> dict[str, float | None]:
    """Accuracy and median errors over the correctly recognised trials."""
    ok = [r for r in trials if r.correct]
    out: dict[str, float | None] = {"accuracy": float(len(ok) / len(trials)) if trials else float("nan")}
    for name in (
        "joint_rmse_rad",
        "joint_rmse_prior_rad",
        "final_joint_error_rad",
        "final_joint_error_prior_rad",
        "handover_error_cm",
        "handover_error_prior_cm",
        "duration_error_s",
    ):
        vals = [abs(getattr(r, name)) if name == "duration_error_s" else getattr(r, name) for r in ok]
        out[name] = _median(vals)
    return out


def split_paper(dataset: Dataset, n_train: int, n_test: int) -> tuple[list[Demo], list[Demo]]:
    """First ``n_train`` demos of each task train, the next ``n_test`` test."""
    return _take(dataset, _paper_indices(dataset, n_train, n_test))


def split_random(
    dataset: Dataset, n_train: int, n_test: int, rng: np.random.Generator
) -> tuple[list[Demo], list[Demo]]:
    """A random split per task: ``n_train`` demos train, up to ``n_test`` of the others test."""
    return _take(dataset, _random_indices(dataset, n_train, n_test, rng))


Indices = dict[str, tuple[list[int], list[int]]]
"""Task -> (train demo indices, test demo indices)."""


def _check_size(dataset: Dataset, task: str, n_train: int) -> int:
    n = len(dataset.demos[task])
    if n < n_train + 1:
        raise DataError(
            dataset.root, task, f"{n} demos, the protocol needs {n_train} to train and 1+ to test"
        )
    return n


def check_dataset_size(counts: Mapping[str, int], config: EvaluationConfig, source: object = None) -> None:
    """Check, before any model is fitted, that every task has enough demos for ``config``.

    Every cell needs ``n_train`` training demos and at least one test demo per task; the paper
    protocol's largest cell trains on 20 (21 demos per task). Raises a :class:`DataError` naming
    the smallest task and the settings that fit it (``--protocol splits`` with a smaller
    ``--n-train``).

    Args:
        counts: Task -> number of demos.
        config: The evaluation settings.
        source: The dataset (folder) named in the error.
    """
    need = max(n for n, _ in config.grid) + 1
    task, have = min(counts.items(), key=lambda kv: kv[1])
    if have >= need:
        return
    fits = [n for n in sorted({n for n, _ in config.grid} | {5, 10, 15}) if n < have] or [have - 1]
    raise DataError(
        source,
        None,
        f"too small for the {config.protocol} protocol: task '{task}' has {have} demos, cells up to "
        f"n_train={need - 1} need {need} per task (n_train to train, 1+ to test); use --protocol splits "
        f"--grid full --n-train {' '.join(str(n) for n in fits)}",
    )


def _paper_indices(dataset: Dataset, n_train: int, n_test: int) -> Indices:
    out = {}
    for task in dataset.tasks:
        n = _check_size(dataset, task, n_train)
        out[task] = (list(range(n_train)), list(range(n_train, min(n, n_train + n_test))))
    return out


def _random_indices(dataset: Dataset, n_train: int, n_test: int, rng: np.random.Generator) -> Indices:
    out = {}
    for task in dataset.tasks:
        idx = rng.permutation(_check_size(dataset, task, n_train)).tolist()
        out[task] = (idx[:n_train], idx[n_train : n_train + n_test])
    return out


def _take(dataset: Dataset, indices: Indices) -> tuple[list[Demo], list[Demo]]:
    train = [dataset.demos[t][i] for t, (tr, _) in indices.items() for i in tr]
    test = [dataset.demos[t][i] for t, (_, te) in indices.items() for i in te]
    return train, test


@dataclass
class EvaluationConfig:
    """Settings of an evaluation run.

    Attributes:
        protocol: ``"paper"`` or ``"splits"``.
        observe: Observed channel sets, each a list of group names.
        grid: (n_train, obs_ratio) cells.
        n_test: Test demos per task.
        n_splits: Random splits (``splits`` protocol).
        seed: Seed of the random splits.
        model_params: Keyword arguments of the model's constructor.
        baselines: Also run the reference baselines on the same windows
            (:mod:`ipromp_pin.evaluation.baselines`).
    """

    protocol: str = "paper"
    observe: list[list[str]] = field(default_factory=lambda: [["orientation"], ["orientation", "emg"]])
    grid: list[tuple[int, float]] = field(default_factory=lambda: list(PAPER_GRID))
    n_test: int = 10
    n_splits: int = 20
    seed: int = 0
    model_params: dict = field(default_factory=dict)
    baselines: bool = False


@dataclass
class _Job:
    """One model fit of a protocol: a split, a training size and an observed set."""

    rep: int
    n_train: int
    observe: list[str]
    indices: Indices
    ratios: list[float]


_WORKER: dict = {}
"""Per-process state of the evaluation workers (dataset, settings), set before forking."""


def _run_job(job: _Job) -> tuple[_Job, dict[float, list[TrialResult]], str]:
    """Fit on the job's training demos and score its test demos at every ratio.

    Returns:
        The job, per ratio the trials, and the observed groups the fitted model couples to the
        robot (``"+"``-joined).
    """
    dataset: Dataset = _WORKER["dataset"]
    fk = _WORKER["fk"]
    train, test = _take(dataset, job.indices)
    model = IProMP(observe=list(job.observe), **_WORKER["params"]).fit(train, fk=fk)
    out = {}
    for ratio in job.ratios:
        out[ratio] = [
            score_trial(model.predict(d.head(ratio, groups=job.observe)), d, ratio, fk) for d in test
        ]
        if _WORKER["baselines"]:
            scored = WindowBaselines(job.observe, ratio, fk).fit(train).score(test)
            for trial, base in zip(out[ratio], scored, strict=True):
                trial.baselines = base
    return job, out, "+".join(getattr(model, "coupled_groups_", job.observe))


def _robot_fk(robot: str | None) -> Callable[[np.ndarray], np.ndarray] | None:
    if robot is None:
        return None
    loaded = load_robot(robot)
    return lambda q: ee_positions(loaded, q)


def evaluate(
    dataset: Dataset,
    config: EvaluationConfig,
    robot: str | None = DEFAULT_ROBOT,
    progress: ProgressFn | None = None,
    jobs: int = 1,
) -> list[Cell]:
    """Run one protocol over every cell of ``config`` and return the table.

    Args:
        dataset: Demos of every task, in protocol order.
        config: Protocol, grid and observed channel sets.
        robot: Robot settings (name or file) for the hand-over position error through forward
            kinematics; ``None`` skips it.
        progress: Called as ``progress(done, total, label)`` after every model fit.
        jobs: Worker processes (model fits run in parallel; results do not depend on it).
    """
    if config.protocol not in ("paper", "splits"):
        raise DataError(None, "protocol", f"unknown protocol '{config.protocol}' (use paper or splits)")
    check_dataset_size({t: len(d) for t, d in dataset.demos.items()}, config, dataset.root)
    for observe in config.observe:
        for demo in dataset.all_demos():
            demo.require(list(observe) + [ROBOT])
    n_train_values = sorted({n for n, _ in config.grid}, reverse=True)
    repeats = 1 if config.protocol == "paper" else config.n_splits
    rng = np.random.default_rng(config.seed)
    work = []
    for rep in range(repeats):
        for n_train in n_train_values:
            if config.protocol == "paper":
                indices = _paper_indices(dataset, n_train, config.n_test)
            else:
                indices = _random_indices(dataset, n_train, config.n_test, rng)
            ratios = [r for n, r in config.grid if n == n_train]
            work += [_Job(rep, n_train, list(o), indices, ratios) for o in config.observe]
    _WORKER.update(
        dataset=dataset, fk=_robot_fk(robot), params=dict(config.model_params), baselines=config.baselines
    )
    # (n_train, ratio, observe_key, task) -> per repeat, the trials of that task
    results: dict[tuple[int, float, str, str], list[list[TrialResult]]] = {}
    # (n_train, observe_key) -> coupled groups of the fitted models -> number of fits
    couplings: dict[tuple[int, str], dict[str, int]] = {}
    try:
        for done, (job, trials, coupled) in enumerate(run_jobs(_run_job, work, jobs), start=1):
            key = observe_key(job.observe)
            counts = couplings.setdefault((job.n_train, key), {})
            counts[coupled] = counts.get(coupled, 0) + 1
            for ratio, rows in trials.items():
                for task in dataset.tasks:
                    results.setdefault((job.n_train, ratio, key, task), []).append(
                        [r for r in rows if r.task == task]
                    )
            if progress is not None:
                label = f"{config.protocol} split {job.rep + 1}/{repeats} n_train={job.n_train} {key}"
                progress(done, len(work), label)
    finally:
        _WORKER.clear()
    return _cells(dataset, config, results, couplings)


def run_jobs(run: Callable[[J], R], work: list[J], jobs: int) -> Iterator[R]:
    """``run`` over the jobs, in ``jobs`` forked worker processes when > 1 (results in completion
    order; the workers inherit the parent's module state, e.g. a dataset set before the call)."""
    if jobs <= 1 or len(work) <= 1:
        yield from map(run, work)
        return
    with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("fork")) as pool:
        futures = [pool.submit(run, job) for job in work]
        for f in as_completed(futures):
            yield f.result()


def cell_fields(
    dataset: Dataset,
    config: EvaluationConfig,
    where: tuple[int, float, Sequence[str], str],
    n_test: int,
    accs: Sequence[float],
    summary: Mapping[str, float | None],
) -> dict:
    """The :class:`Cell` fields shared by every evaluation of one cell ``where`` = (n_train, obs
    ratio, observed groups, task): ``accs`` the accuracies per split (or the one of the paper's
    protocol), ``summary`` the :func:`summarise` of all its test trials."""
    n_train, ratio, observe, task = where
    paper = PAPER_ACCURACY.get((n_train, ratio, observe_key(observe)), {}).get(task)
    errors = (
        "joint_rmse_rad",
        "joint_rmse_prior_rad",
        "final_joint_error_rad",
        "final_joint_error_prior_rad",
        "handover_error_cm",
        "handover_error_prior_cm",
        "duration_error_s",
    )
    return {
        "protocol": config.protocol,
        "n_train": n_train,
        "obs_ratio": ratio,
        "observe": list(observe),
        "task": task,
        "accuracy": float(np.mean(accs)) if accs else float("nan"),
        "n_test": n_test,
        "paper_accuracy": paper if Path(str(dataset.root)).name == "chen2017_handover" else None,
        **{name: summary[name] for name in errors},
    }


def _cells(dataset: Dataset, config: EvaluationConfig, results, couplings) -> list[Cell]:
    cells = []
    for n_train, ratio in config.grid:
        for observe in config.observe:
            key = observe_key(observe)
            for task in dataset.tasks:
                reps = results[(n_train, ratio, key, task)]
                flat = [r for rep in reps for r in rep]
                summary = summarise(flat)
                accs = [summarise(rep)["accuracy"] for rep in reps if rep]
                cell = Cell(
                    **cell_fields(dataset, config, (n_train, ratio, observe, task), len(flat), accs, summary),
                    coupled_groups=dict(sorted(couplings.get((n_train, key), {}).items())),
                )
                cell.log_loss, cell.brier = _calibration([(r.posterior, r.brier) for r in flat])
                cell.baselines = _baseline_summary(reps, config.protocol == "splits")
                if config.protocol == "splits":
                    cell.accuracy_std = float(np.std(accs)) if accs else float("nan")
                    cell.n_splits = len(accs)
                else:
                    cell.trials = [asdict(r) | {"correct": r.correct} for r in flat]
                cells.append(cell)
    return cells


def _calibration(rows: Sequence[tuple[float, float]]) -> tuple[float | None, float | None]:
    """Mean log loss and mean Brier score of (posterior of the true task, Brier score) rows."""
    if not rows:
        return None, None
    p = np.maximum(np.array([r[0] for r in rows], dtype=float), PROBABILITY_FLOOR)
    return float(np.mean(-np.log(p))), float(np.mean([r[1] for r in rows]))


def _baseline_summary(reps: list[list[TrialResult]], splits: bool) -> dict[str, dict[str, float | None]]:
    """Baseline name -> its summary over a cell's trials (see :class:`Cell`)."""
    flat = [r for rep in reps for r in rep]
    out: dict[str, dict[str, float | None]] = {}
    for name in CLASSIFIERS:
        rows = [r.baselines[name] for r in flat if name in r.baselines]
        if not rows:
            continue
        task = flat[0].task
        accs = [np.mean([r.baselines[name].predicted == task for r in rep]) for rep in reps if rep]
        log_loss, brier = _calibration([(b.posterior, b.brier) for b in rows])
        out[name] = {"accuracy": float(np.mean(accs)), "log_loss": log_loss, "brier": brier}
        if splits:
            out[name]["accuracy_std"] = float(np.std(accs))
    for name in REGRESSORS:
        rows = [r.baselines[name] for r in flat if r.correct and name in r.baselines]
        if not any(name in r.baselines for r in flat):
            continue
        out[name] = {
            key: _median([getattr(b, key) for b in rows])
            for key in ("joint_rmse_rad", "final_joint_error_rad", "handover_error_cm")
        }
    return out


def overall(cells: Sequence[Cell]) -> dict[str, dict[str, float]]:
    """Mean accuracy per (protocol, observed set), with the paper's mean where known."""
    out: dict[str, dict[str, float]] = {}
    for c in cells:
        key = f"{c.protocol}:{observe_key(c.observe)}"
        out.setdefault(key, {"cells": 0, "accuracy_sum": 0.0, "paper_sum": 0.0, "paper_cells": 0})
        o = out[key]
        o["cells"] += 1
        o["accuracy_sum"] += c.accuracy
        if c.paper_accuracy is not None:
            o["paper_sum"] += c.paper_accuracy
            o["paper_cells"] += 1
    result = {}
    for key, o in out.items():
        result[key] = {"mean_accuracy": o["accuracy_sum"] / o["cells"], "cells": o["cells"]}
        if o["paper_cells"]:
            result[key]["paper_mean_accuracy"] = o["paper_sum"] / o["paper_cells"]
            result[key]["cells_below_paper"] = sum(
                1
                for c in cells
                if f"{c.protocol}:{observe_key(c.observe)}" == key
                and c.paper_accuracy is not None
                and c.accuracy < c.paper_accuracy - 1e-9
            )
    return result


def format_number(x: float | None, digits: int = 2) -> str:
    """``x`` with ``digits`` decimals for a table, ``-`` when it is missing or not finite."""
    return "-" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


_fmt = format_number


def to_markdown(cells: Sequence[Cell]) -> str:
    """The accuracy table (and prediction errors) as Markdown."""
    lines = []
    for protocol in dict.fromkeys(c.protocol for c in cells):
        pc = [c for c in cells if c.protocol == protocol]
        tasks = list(dict.fromkeys(c.task for c in pc))
        lines.append(f"### Recognition accuracy, protocol `{protocol}`\n")
        head = "| n_train | obs ratio | observed | " + " | ".join(tasks) + " | mean |"
        lines += [head, "|" + "---|" * (4 + len(tasks))]
        rows = dict.fromkeys((c.n_train, c.obs_ratio, observe_key(c.observe)) for c in pc)
        for n_train, ratio, key in rows:
            row = [c for c in pc if (c.n_train, c.obs_ratio, observe_key(c.observe)) == (n_train, ratio, key)]
            texts = []
            for task in tasks:
                c = next(c for c in row if c.task == task)
                s = _fmt(c.accuracy)
                if c.accuracy_std is not None:
                    s += f" ± {_fmt(c.accuracy_std)}"
                if c.paper_accuracy is not None:
                    s += f" (paper {_fmt(c.paper_accuracy)})"
                texts.append(s)
            mean = float(np.mean([c.accuracy for c in row]))
            lines.append(f"| {n_train} | {ratio:g} | {key} | " + " | ".join(texts) + f" | {_fmt(mean)} |")
        lines.append("")
        for key, o in overall(pc).items():
            s = f"- mean over cells, {key.split(':', 1)[1]}: {o['mean_accuracy']:.3f}"
            if "paper_mean_accuracy" in o:
                s += f" (paper {o['paper_mean_accuracy']:.3f}; cells below it: {o['cells_below_paper']})"
            lines.append(s)
        lines.append("")
        lines.append(
            f"### Robot motion prediction, protocol `{protocol}` "
            "(medians over correctly recognised trials; conditioned vs prior mean)\n"
        )
        lines.append(
            "| n_train | obs ratio | observed | task | joint RMSE [rad] | final joint err [rad] "
            "| hand-over err [cm] | duration err [s] |"
        )
        lines.append("|---|---|---|---|---|---|---|---|")
        for c in pc:
            lines.append(
                f"| {c.n_train} | {c.obs_ratio:g} | {observe_key(c.observe)} | {c.task} "
                f"| {_fmt(c.joint_rmse_rad, 3)} vs {_fmt(c.joint_rmse_prior_rad, 3)} "
                f"| {_fmt(c.final_joint_error_rad, 3)} vs {_fmt(c.final_joint_error_prior_rad, 3)} "
                f"| {_fmt(c.handover_error_cm, 1)} vs {_fmt(c.handover_error_prior_cm, 1)} "
                f"| {_fmt(c.duration_error_s, 2)} |"
            )
        lines.append("")
        if any(c.baselines for c in pc):
            lines += baseline_markdown(pc)
        fits = {(c.n_train, observe_key(c.observe)): c.coupled_groups for c in pc if c.coupled_groups}
        for (n_train, key), counts in fits.items():
            chosen = ", ".join(f"{g or 'none'} ({n})" for g, n in counts.items())
            lines.append(f"- observed groups coupled to the robot, n_train={n_train}, {key}: {chosen}")
        if fits:
            lines.append("")
    return "\n".join(lines)


def _row_mean(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else None


def baseline_markdown(cells: Sequence[Cell]) -> list[str]:
    """Markdown lines: ipromp_pin beside the baselines, one row per (n_train, ratio, observed set),
    each number the mean over the row's tasks (of the per-task accuracy, log loss, or median error)."""
    protocol = cells[0].protocol
    rows: dict[tuple[int, float, str], list[Cell]] = {}
    for c in cells:
        rows.setdefault((c.n_train, c.obs_ratio, observe_key(c.observe)), []).append(c)
    names = ["ipromp_pin", *CLASSIFIERS]
    lines = [
        f"### ipromp_pin and the baselines, protocol `{protocol}` (means over tasks)\n",
        "| n_train | obs ratio | observed | accuracy: "
        + " / ".join(names)
        + " | log loss: "
        + " / ".join(names)
        + " | hand-over err [cm]: ipromp_pin / "
        + " / ".join(REGRESSORS)
        + " | joint RMSE [rad]: ipromp_pin / "
        + " / ".join(REGRESSORS)
        + " |",
        "|---|---|---|---|---|---|---|",
    ]

    def base(row: list[Cell], name: str, key: str) -> float | None:
        return _row_mean([c.baselines.get(name, {}).get(key) for c in row])

    for (n_train, ratio, key), row in rows.items():
        acc = [_row_mean([c.accuracy for c in row])] + [base(row, n, "accuracy") for n in CLASSIFIERS]
        loss = [_row_mean([c.log_loss for c in row])] + [base(row, n, "log_loss") for n in CLASSIFIERS]
        ho = [_row_mean([c.handover_error_cm for c in row])] + [
            base(row, n, "handover_error_cm") for n in REGRESSORS
        ]
        rmse = [_row_mean([c.joint_rmse_rad for c in row])] + [
            base(row, n, "joint_rmse_rad") for n in REGRESSORS
        ]
        lines.append(
            f"| {n_train} | {ratio:g} | {key} | "
            + " / ".join(_fmt(v) for v in acc) + " | " + " / ".join(_fmt(v) for v in loss) + " | "
            + " / ".join(_fmt(v, 1) for v in ho) + " | " + " / ".join(_fmt(v, 3) for v in rmse) + " |"
        )  # fmt: skip
    lines.append("")
    return lines


def to_json(cells: Sequence[Cell], meta: dict | None = None) -> dict:
    """JSON document: ``cells`` (one record per table cell), ``overall`` and ``meta``.

    Undefined numbers (e.g. an error median over no correctly recognised trial) are ``null``.
    """
    return _finite(
        {
            "format": "ipromp_pin.evaluation",
            "version": 1,
            "meta": meta or {},
            "overall": overall(cells),
            "cells": [asdict(c) for c in cells],
        }
    )


def _finite(x):
    """``x`` with NaN and inf floats replaced by ``None`` (strict JSON) and numpy scalars made plain."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def write_results(cells: Sequence[Cell], json_path: Path | None, md_path: Path | None, meta: dict) -> None:
    """Write the JSON and Markdown results (each atomically: a temporary file renamed into place)."""
    if json_path is not None:
        atomic.write_text(json_path, json.dumps(to_json(cells, meta), indent=1, allow_nan=False))
    if md_path is not None:
        atomic.write_text(md_path, to_markdown(cells))
