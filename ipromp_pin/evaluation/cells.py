"""Cells of the evaluation table and the aggregation of trials into them, by (n_train, window,
observed set, task): accuracy (mean over splits), median prediction errors over the correctly
recognised trials, calibration, and the baselines' summaries."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..data import Dataset
from .baselines import CLASSIFIERS, REGRESSORS
from .config import PAPER_ACCURACY, EvaluationConfig, observe_key
from .jobs import JobResult
from .windows import Window

PROBABILITY_FLOOR = 1e-15
"""Posteriors are floored at this value in the log loss (a confident mistake costs at most 34.5)."""

ERROR_FIELDS = (
    "joint_rmse_rad",
    "joint_rmse_prior_rad",
    "final_joint_error_rad",
    "final_joint_error_prior_rad",
    "handover_error_cm",
    "handover_error_prior_cm",
    "duration_error_s",
    "handover_orientation_error_deg",
    "handover_orientation_baseline_deg",
)
"""The prediction errors of a trial summarised (median) in a cell."""

CellKey = tuple[int, Window, str, str]
"""(n_train, window, observe_key, task)."""


@dataclass
class Cell:
    """One cell of the accuracy table: a protocol, training size, window, observed set and task.

    ``window`` says how much of each test demo was observed (:mod:`~.windows`): ``{"kind": "ratio",
    "value": obs_ratio, "seconds": None}`` (the paper's fraction of each test demo; ``obs_ratio`` is
    that fraction), ``{"kind": "seconds", "value": S, "seconds": S}`` or ``{"kind":
    "train_fraction", "value": F, "seconds": F x the median over the cell's fits of their training
    demos' mean length}`` (``obs_ratio`` is None for both). ``observed_s`` and ``observed_fraction``
    are the medians over the cell's test trials of the last observed sample's time [s] and of the
    fraction of the test demo's length the window covered.

    ``coupled_groups`` counts, over the cell's model fits, the observed groups each fitted model
    coupled to the robot (``"+"``-joined, ``""`` for none; see ``IProMP(coupling=...)``).
    ``log_loss`` (mean of ``-log p(true task)``, posteriors floored at :data:`PROBABILITY_FLOOR`) and
    ``brier`` (mean multi-class Brier score) say how well calibrated the task posterior is, and ``ece``
    (:func:`expected_calibration_error` of the recognised task's posterior) whether its confidence
    is the accuracy it has.
    ``baselines`` (``--baselines``): baseline name -> ``accuracy``, ``log_loss``, ``brier``, ``ece`` (and
    ``accuracy_std`` over splits) for the classifiers, the median ``handover_error_cm``,
    ``joint_rmse_rad`` and ``final_joint_error_rad`` over the trials ipromp_pin recognised for the
    regressors (the true task given to them).
    ``plans`` (one-shot plans on the executing arm, ``evaluate --robot NAME`` of a placed arm or
    ``--plan``): :func:`~.arm_plans.plan_summary` of the cell's trials (None: not planned).
    """

    protocol: str
    n_train: int
    obs_ratio: float | None
    observe: list[str]
    task: str
    accuracy: float
    n_test: int
    window: dict[str, Any] = field(default_factory=dict)
    observed_s: float | None = None
    observed_fraction: float | None = None
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
    handover_orientation_error_deg: float | None = None
    handover_orientation_baseline_deg: float | None = None
    peak_torque_ratio: float | None = None
    coupled_groups: dict[str, int] = field(default_factory=dict)
    log_loss: float | None = None
    brier: float | None = None
    ece: float | None = None
    baselines: dict[str, dict[str, float | None]] = field(default_factory=dict)
    plans: dict[str, Any] | None = None
    trials: list[dict] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.window and self.obs_ratio is not None:
            self.window = Window("ratio", self.obs_ratio).to_dict()

    @property
    def window_kind(self) -> str:
        """The kind of the cell's window (``"ratio"``, ``"seconds"``, ``"train_fraction"``)."""
        return str(self.window.get("kind", "ratio"))

    def window_label(self) -> str:
        """The window in a table: ``0.2`` (a fraction of each test demo), ``0.6 s``, ``0.2 of train
        (0.63 s)`` (the fraction of the training demos' mean length, and its seconds)."""
        w = self.window
        label = Window(str(w["kind"]), float(w["value"])).label()
        if w["kind"] == "train_fraction" and w.get("seconds") is not None:
            label += f" ({w['seconds']:.2f} s)"
        return label


@dataclass
class ClosedLoopCell(Cell):
    """An evaluation cell with the closed-loop measures (medians over all its test trials).

    The human measures (datasets with a tracked skeleton, against the recorded human; None without):
    ``human_min_separation_m`` (minimum over the trials, outside the hand region),
    ``protective_distance_time_s`` (median time closer than ``S_p``), ``contact_speed_violations``
    (sum of the control samples inside ``S_p`` faster than the contact-speed limit) and
    ``arrival_delay_without_human_s`` (median arrival delay of the replays without the human checks).
    ``robot_start_s`` is the median time the robot started, [s] from the motion start;
    ``never_started`` counts the replays in which it never did (no re-plan: the observation matched
    none of the tasks throughout, ``require_known``; their hand-over error is from the rest pose),
    ``stopped_unknown`` those in which it stopped because the observation turned unknown after it
    started and ``retreated`` those in which it then retreated (:mod:`~ipromp_pin.planning.unknown_stop`).
    ``arm``: the re-plans on an arm executing a model of another robot
    (:func:`~.arm_plans.replay_arm_summary`; None: the arm's own model).
    """

    limit_profile: str = ""
    closed_loop_handover_error_cm: float | None = None
    closed_loop_final_error_cm: float | None = None
    one_shot_handover_error_cm: float | None = None
    arrival_delay_s: float | None = None
    robot_start_s: float | None = None
    max_limit_ratio: float | None = None
    refused_replans: int = 0
    replans: int = 0
    never_started: int = 0
    stopped_unknown: int = 0
    retreated: int = 0
    collisions: int = 0
    closed_loop_handover_orientation_error_deg: float | None = None
    human_min_separation_m: float | None = None
    protective_distance_time_s: float | None = None
    contact_speed_violations: int | None = None
    arrival_delay_without_human_s: float | None = None
    arm: dict[str, Any] | None = None
    closed_loop_trials: list[dict] = field(default_factory=list)


def median(values: Sequence[float | None]) -> float | None:
    """Median of the finite values (None and NaN skipped); None when there is none."""
    arr = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    return float(np.median(arr)) if arr.size else None


def accuracy(trials: Sequence) -> float:
    """Fraction of the trials (``TrialResult``-like: ``correct``) recognised; NaN for none."""
    ok = [r for r in trials if r.correct]
    return float(len(ok) / len(trials)) if trials else float("nan")


def summarise(trials: Sequence) -> dict[str, float | None]:
    """Accuracy and median errors over the correctly recognised trials (``TrialResult``-like:
    ``correct`` and the :data:`ERROR_FIELDS`)."""
    ok = [r for r in trials if r.correct]
    out: dict[str, float | None] = {"accuracy": accuracy(trials)}
    for name in ERROR_FIELDS:
        vals = [abs(getattr(r, name)) if name == "duration_error_s" else getattr(r, name) for r in ok]
        out[name] = median(vals)
    return out


def observed(trials: Sequence) -> dict[str, float | None]:
    """Medians over all the trials (``TrialResult``-like) of ``observed_s`` and ``observed_fraction``
    (None when no trial has them)."""
    return {
        name: median([getattr(r, name, None) for r in trials]) for name in ("observed_s", "observed_fraction")
    }


def calibration(rows: Sequence[tuple[float, float]]) -> tuple[float | None, float | None]:
    """Mean log loss and mean Brier score of (posterior of the true task, Brier score) rows."""
    if not rows:
        return None, None
    p = np.maximum(np.array([r[0] for r in rows], dtype=float), PROBABILITY_FLOOR)
    return float(np.mean(-np.log(p))), float(np.mean([r[1] for r in rows]))


ECE_BINS = 10
"""Equal-width confidence bins over [0, 1] of the expected calibration error."""


def expected_calibration_error(rows: Sequence[tuple[float, bool]]) -> float | None:
    """Expected calibration error of (confidence, correct) rows: the confidence of the recognised
    task binned in :data:`ECE_BINS` equal-width bins, the mean over rows of |accuracy - mean
    confidence| of their bin (Guo et al. 2017); None for no row (NaN confidences skipped)."""
    conf = np.array([c for c, _ in rows], dtype=float)
    ok = np.array([k for _, k in rows], dtype=float)
    keep = np.isfinite(conf)
    conf, ok = conf[keep], ok[keep]
    if conf.size == 0:
        return None
    bins = np.minimum((conf * ECE_BINS).astype(int), ECE_BINS - 1)
    gap = sum(abs(ok[bins == b].sum() - conf[bins == b].sum()) for b in range(ECE_BINS))
    return float(gap / conf.size)


def baseline_summary(reps: Sequence[Sequence], splits: bool) -> dict[str, dict[str, float | None]]:
    """Baseline name -> its summary over a cell's trials per split (see :class:`Cell`)."""
    flat = [r for rep in reps for r in rep]
    out: dict[str, dict[str, float | None]] = {}
    for name in CLASSIFIERS:
        rows = [r.baselines[name] for r in flat if name in r.baselines]
        if not rows:
            continue
        task = flat[0].task
        accs = [np.mean([r.baselines[name].predicted == task for r in rep]) for rep in reps if rep]
        log_loss, brier = calibration([(b.posterior, b.brier) for b in rows])
        ece = expected_calibration_error([(b.confidence, b.predicted == task) for b in rows])
        out[name] = {"accuracy": float(np.mean(accs)), "log_loss": log_loss, "brier": brier, "ece": ece}
        if splits:
            out[name]["accuracy_std"] = float(np.std(accs))
    for name in REGRESSORS:
        rows = [r.baselines[name] for r in flat if r.correct and name in r.baselines]
        if not any(name in r.baselines for r in flat):
            continue
        out[name] = {
            key: median([getattr(b, key) for b in rows])
            for key in ("joint_rmse_rad", "final_joint_error_rad", "handover_error_cm")
        }
    return out


def cell_fields(
    dataset: Dataset,
    config: EvaluationConfig,
    where: tuple[int, float | Window, Sequence[str], str],
    n_test: int,
    accs: Sequence[float],
    summary: Mapping[str, float | None],
    window_s: float | None = None,
) -> dict:
    """The :class:`Cell` fields shared by every evaluation of one cell ``where`` = (n_train, window
    (a bare float: an observed ratio), observed groups, task): ``accs`` the accuracies per split (or
    the one of the paper's protocol), ``summary`` the :func:`summarise` of all its test trials,
    ``window_s`` the window's end in [s] (a ``train_fraction`` window's, over the cell's fits).
    Only a ratio window's cells have the paper's accuracy: the paper observed fractions."""
    n_train, window, observe, task = where
    window = Window.of(window)
    ratio = window.value if window.is_ratio else None
    paper = PAPER_ACCURACY.get((n_train, ratio, observe_key(observe)), {}).get(task) if ratio else None
    return {
        "protocol": config.protocol,
        "n_train": n_train,
        "obs_ratio": ratio,
        "observe": list(observe),
        "task": task,
        "accuracy": float(np.mean(accs)) if accs else float("nan"),
        "n_test": n_test,
        "window": window.to_dict(window_s),
        "observed_s": summary.get("observed_s"),
        "observed_fraction": summary.get("observed_fraction"),
        "paper_accuracy": paper if Path(str(dataset.root)).name == "chen2017_handover" else None,
        **{name: summary[name] for name in ERROR_FIELDS},
    }


class CellResults:
    """The trials of every job, grouped by cell, and the facts of every fit (in completion order).

    Attributes:
        trials: (n_train, window, observe_key, task) -> per split, the trials of that task.
        couplings: (n_train, observe_key) -> coupled groups of the fitted models -> number of fits.
        fits: The ``fit`` facts of every job, in completion order.
        nominal_s: (n_train, observe_key) -> the nominal duration [s] of every fit (the mean length
            of its training demos).
    """

    def __init__(self, tasks: Sequence[str]) -> None:
        self.tasks = list(tasks)
        self.trials: dict[CellKey, list[list]] = {}
        self.couplings: dict[tuple[int, str], dict[str, int]] = {}
        self.fits: list[dict[str, str]] = []
        self.nominal_s: dict[tuple[int, str], list[float]] = {}

    def add(self, result: JobResult) -> None:
        """Add one job's trials and fit facts."""
        job = result.job
        key = observe_key(job.observe)
        counts = self.couplings.setdefault((job.n_train, key), {})
        coupled = result.fit.get("coupled", "")
        counts[coupled] = counts.get(coupled, 0) + 1
        self.fits.append(result.fit)
        self.nominal_s.setdefault((job.n_train, key), []).append(result.nominal_s)
        for window, rows in result.trials.items():
            for task in self.tasks:
                self.trials.setdefault((job.n_train, window, key, task), []).append(
                    [r for r in rows if r.task == task]
                )

    def window_s(self, n_train: int, window: Window, key: str) -> float | None:
        """The end [s] of a ``train_fraction`` window over the cell's fits (its fraction of the
        median of their nominal durations); a ``seconds`` window's value; None for a ratio."""
        if window.kind == "train_fraction":
            return window.value * float(np.median(self.nominal_s[(n_train, key)]))
        return window.value if window.kind == "seconds" else None


def build_cells(
    dataset: Dataset,
    config: EvaluationConfig,
    results: CellResults,
    cell_type: type[Cell] = Cell,
    extra_fields=None,
) -> list[Cell]:
    """The cells of ``config`` (grid, then observed set, then task) from the grouped ``results``.

    Args:
        cell_type: The cell class (:class:`Cell` or a subclass with more fields).
        extra_fields: Called as ``extra_fields(reps, config, results)`` with a cell's trials per
            split; returns the fields of ``cell_type`` beyond the shared ones (see the scorers'
            ``cell_fields``).
    """
    cells = []
    for n_train, window in config.cells():
        for observe in config.observe:
            key = observe_key(observe)
            for task in dataset.tasks:
                reps = results.trials[(n_train, window, key, task)]
                flat = [r for rep in reps for r in rep]
                accs = [accuracy(rep) for rep in reps if rep]
                where = (n_train, window, observe, task)
                summary = summarise(flat) | observed(flat)
                window_s = results.window_s(n_train, window, key)
                cell = cell_type(
                    **cell_fields(dataset, config, where, len(flat), accs, summary, window_s),
                    coupled_groups=dict(sorted(results.couplings.get((n_train, key), {}).items())),
                    **(extra_fields(reps, config, results) if extra_fields is not None else {}),
                )
                if config.protocol == "splits":
                    cell.accuracy_std = float(np.std(accs)) if accs else float("nan")
                    cell.n_splits = len(accs)
                cells.append(cell)
    return cells
