"""``ipromp-pin evaluate --closed-loop``: every test demo of every cell replayed in the closed loop.

The cells, splits and model fits are those of :func:`ipromp_pin.evaluation.evaluate.evaluate` (same random
splits for the same seed). For every fit the limit profile is derived from that fit's training
demos (``demonstrated``) or taken from the settings (``conservative``) or a profile file; every test
demo is then

* predicted once from its first ``obs_ratio`` (the one-shot prediction, scored as ``evaluate`` does:
  recognition, joint errors, ``one_shot_handover_error_cm`` = the gripper position error of the
  one-shot plan's end, which is the prediction's last point);
* replayed at its recorded timing with ``obs_ratio`` as the start ratio
  (:func:`~ipromp_pin.handover.closed_loop.replay_demo`) and scored
  (:func:`~ipromp_pin.handover.score.score_closed_loop`).

Each cell gains, over all its test trials (recognised or not): ``closed_loop_handover_error_cm``,
``closed_loop_final_error_cm``, ``one_shot_handover_error_cm``, ``arrival_delay_s`` (medians),
``max_limit_ratio`` (maximum), ``refused_replans``, ``replans`` and ``collisions`` (sums).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..handover.closed_loop import ClosedLoopSettings, conditioning_predictor, replay_demo
from ..handover.score import score_closed_loop
from ..motion.limits import LimitProfile, conservative_profile, demonstrated_profile, read_limit_profile
from ..promp import IProMP
from ..robot import DemoLimitRecipe, Robot, ee_positions, load_robot
from ..robot.clearance import ClearanceCertifier
from ..shipped import DEFAULT_ROBOT
from .evaluate import (
    Cell,
    EvaluationConfig,
    cell_fields,
    observe_key,
    run_jobs,
    score_trial,
    split_paper,
    split_random,
    summarise,
    to_json,
    to_markdown,
)
from .evaluate import format_number as _fmt

ProgressFn = Callable[[int, int, str], None]


@dataclass(frozen=True)
class ClosedLoopOptions:
    """How the closed loop is run in an evaluation.

    Attributes:
        limits: ``"demonstrated"``, ``"conservative"`` or a limit profile file.
        settings: Closed-loop settings; each cell's ``obs_ratio`` replaces ``start_ratio``.
        recipe: How the demonstrated profile is derived (default: the robot settings').
        check_collisions: Contact-test every commanded control sample.
    """

    limits: str = "demonstrated"
    settings: ClosedLoopSettings = field(default_factory=ClosedLoopSettings)
    recipe: DemoLimitRecipe | None = None
    check_collisions: bool = True


@dataclass
class ClosedLoopCell(Cell):
    """An evaluation cell with the closed-loop measures (medians over all its test trials)."""

    limit_profile: str = ""
    closed_loop_handover_error_cm: float | None = None
    closed_loop_final_error_cm: float | None = None
    one_shot_handover_error_cm: float | None = None
    arrival_delay_s: float | None = None
    max_limit_ratio: float | None = None
    refused_replans: int = 0
    replans: int = 0
    collisions: int = 0
    closed_loop_trials: list[dict] = field(default_factory=list)


def profile_for(options: ClosedLoopOptions, robot: Robot, train: Sequence[Demo], label: str) -> LimitProfile:
    """The limit profile of one model fit (the demonstrated one from its training demos)."""
    if options.limits == "conservative":
        return conservative_profile(robot)
    if options.limits == "demonstrated":
        recipe = options.recipe or robot.settings.demonstrated_limits
        return demonstrated_profile(robot, train, recipe, label)
    return read_limit_profile(options.limits, robot)


def closed_loop_trials(
    model: IProMP,
    robot: Robot,
    test: Sequence[Demo],
    ratio: float,
    profile: LimitProfile,
    settings: ClosedLoopSettings,
    certifier: ClearanceCertifier | None = None,
    check_collisions: bool = True,
) -> list[dict]:
    """Replay every test demo with ``ratio`` as the start ratio; one record per demo (the one-shot
    prediction's :class:`~ipromp_pin.evaluation.evaluate.TrialResult` fields, then the closed loop's
    :class:`~ipromp_pin.handover.score.ClosedLoopScore` fields prefixed ``closed_loop_``)."""
    observe = list(model.observe_)

    def fk(q: np.ndarray) -> np.ndarray:
        return ee_positions(robot, q)

    run = ClosedLoopSettings(**{**settings.to_dict(), "start_ratio": float(ratio)}).validate()
    conditioner = conditioning_predictor(model, run.condition_noise)
    out = []
    for d in test:
        one_shot = score_trial(model.predict(d.head(ratio, groups=observe)), d, ratio, fk)
        result = replay_demo(model, robot, d, profile, run, certifier, conditioner)
        score = score_closed_loop(result, d, robot, check_collisions=check_collisions)
        row = asdict(one_shot) | {"correct": one_shot.correct}
        row |= {f"closed_loop_{k}": v for k, v in score.to_dict().items()}
        out.append(row)
    return out


@dataclass
class _Job:
    rep: int
    n_train: int
    observe: list[str]
    train: list[tuple[str, int]]
    test: list[tuple[str, int]]
    ratios: list[float]


_WORKER: dict = {}
"""Per-process state of the workers (dataset, robot, certifier, options), set before forking."""


def _demo(ref: tuple[str, int]) -> Demo:
    return _WORKER["dataset"].demos[ref[0]][ref[1]]


def _run_job(job: _Job) -> tuple[_Job, dict[float, list[dict]], str, str]:
    robot: Robot = _WORKER["robot"]
    options: ClosedLoopOptions = _WORKER["options"]
    if "certifier" not in _WORKER:
        _WORKER["certifier"] = ClearanceCertifier(robot)
    train = [_demo(r) for r in job.train]
    test = [_demo(r) for r in job.test]
    fk = partial(ee_positions, robot)  # settings chosen for the hand-over position, as run and evaluate do
    model = IProMP(observe=list(job.observe), **_WORKER["params"]).fit(train, fk=fk)
    profile = profile_for(options, robot, train, _WORKER["label"])
    out = {}
    for ratio in job.ratios:
        rows = closed_loop_trials(
            model,
            robot,
            test,
            ratio,
            profile,
            options.settings,
            _WORKER["certifier"],
            options.check_collisions,
        )
        for row in rows:
            row["split"] = job.rep
        out[ratio] = rows
    return job, out, "+".join(model.coupled_groups_), profile.name


def _refs(dataset: Dataset, demos: list[Demo]) -> list[tuple[str, int]]:
    index = {id(d): (t, i) for t, ds in dataset.demos.items() for i, d in enumerate(ds)}
    return [index[id(d)] for d in demos]


def evaluate_closed_loop(
    dataset: Dataset,
    config: EvaluationConfig,
    options: ClosedLoopOptions | None = None,
    robot: str = DEFAULT_ROBOT,
    progress: ProgressFn | None = None,
    jobs: int = 1,
) -> list[ClosedLoopCell]:
    """Run one protocol with the closed loop over every cell of ``config`` (see the module docstring).

    The random splits are those :func:`~ipromp_pin.evaluation.evaluate.evaluate` draws for the same seed.
    """
    options = options or ClosedLoopOptions()
    options.settings.validate("closed loop")
    if config.protocol not in ("paper", "splits"):
        raise DataError(None, "protocol", f"unknown protocol '{config.protocol}' (use paper or splits)")
    for observe in config.observe:
        for demo in dataset.all_demos():
            demo.require(list(observe) + [ROBOT])
    loaded = load_robot(robot)
    if options.limits not in ("conservative", "demonstrated"):
        read_limit_profile(options.limits, loaded)  # a bad profile file fails before any fit
    n_train_values = sorted({n for n, _ in config.grid}, reverse=True)
    repeats = 1 if config.protocol == "paper" else config.n_splits
    rng = np.random.default_rng(config.seed)
    work = []
    for rep in range(repeats):
        for n_train in n_train_values:
            if config.protocol == "paper":
                train, test = split_paper(dataset, n_train, config.n_test)
            else:
                train, test = split_random(dataset, n_train, config.n_test, rng)
            ratios = [r for n, r in config.grid if n == n_train]
            refs_train, refs_test = _refs(dataset, train), _refs(dataset, test)
            work += [_Job(rep, n_train, list(o), refs_train, refs_test, ratios) for o in config.observe]
    _WORKER.update(
        dataset=dataset,
        robot=loaded,
        options=options,
        params=dict(config.model_params),
        label=Path(str(dataset.root)).name,
    )
    results: dict[tuple[int, float, str, str], list[list[dict]]] = {}
    couplings: dict[tuple[int, str], dict[str, int]] = {}
    profile_name = options.limits
    try:
        for done, (job, trials, coupled, name) in enumerate(run_jobs(_run_job, work, jobs), start=1):
            profile_name = name
            key = observe_key(job.observe)
            counts = couplings.setdefault((job.n_train, key), {})
            counts[coupled] = counts.get(coupled, 0) + 1
            for ratio, rows in trials.items():
                for task in dataset.tasks:
                    results.setdefault((job.n_train, ratio, key, task), []).append(
                        [r for r in rows if r["task"] == task]
                    )
            if progress is not None:
                label = (
                    f"closed loop {config.protocol} split {job.rep + 1}/{repeats} n_train={job.n_train} {key}"
                )
                progress(done, len(work), label)
    finally:
        _WORKER.clear()
    return _cells(dataset, config, results, couplings, profile_name)


def _median(values: list[float]) -> float | None:
    arr = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    return float(np.median(arr)) if arr.size else None


class _Trial:
    """A trial record seen as the ``TrialResult`` attributes :func:`summarise` reads."""

    def __init__(self, row: dict) -> None:
        self.__dict__.update(row)


def _cells(
    dataset: Dataset, config: EvaluationConfig, results, couplings, profile: str
) -> list[ClosedLoopCell]:
    cells = []
    for n_train, ratio in config.grid:
        for observe in config.observe:
            key = observe_key(observe)
            for task in dataset.tasks:
                reps = results[(n_train, ratio, key, task)]
                flat = [r for rep in reps for r in rep]
                summary = summarise([_Trial(r) for r in flat])
                accs = [float(np.mean([r["correct"] for r in rep])) for rep in reps if rep]
                cell = ClosedLoopCell(
                    **cell_fields(dataset, config, (n_train, ratio, observe, task), len(flat), accs, summary),
                    coupled_groups=dict(sorted(couplings.get((n_train, key), {}).items())),
                    limit_profile=profile,
                    closed_loop_handover_error_cm=_median([r["closed_loop_handover_error_cm"] for r in flat]),
                    closed_loop_final_error_cm=_median([r["closed_loop_final_error_cm"] for r in flat]),
                    one_shot_handover_error_cm=_median([r["handover_error_cm"] for r in flat]),
                    arrival_delay_s=_median([r["closed_loop_arrival_delay_s"] for r in flat]),
                    max_limit_ratio=max((r["closed_loop_max_limit_ratio"] for r in flat), default=None),
                    refused_replans=int(sum(r["closed_loop_refused_replans"] for r in flat)),
                    replans=int(sum(r["closed_loop_replans"] for r in flat)),
                    collisions=int(sum(r["closed_loop_collisions"] for r in flat)),
                    closed_loop_trials=[_compact(r) for r in flat],
                )
                if config.protocol == "splits":
                    cell.accuracy_std = float(np.std(accs)) if accs else float("nan")
                    cell.n_splits = len(accs)
                cells.append(cell)
    return cells


_TRIAL_KEYS = (
    "split",
    "demo",
    "predicted",
    "correct",
    "handover_error_cm",
    "closed_loop_handover_error_cm",
    "closed_loop_final_error_cm",
    "closed_loop_arrival_delay_s",
    "closed_loop_max_limit_ratio",
    "closed_loop_replans",
    "closed_loop_refused_replans",
    "closed_loop_collisions",
    "closed_loop_final_task",
)


def _compact(row: dict) -> dict:
    out = {k: row[k] for k in _TRIAL_KEYS if k in row}
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in out.items()}


def closed_loop_markdown(cells: Sequence[ClosedLoopCell]) -> str:
    """The closed-loop table (one row per cell) and its medians over cells, as Markdown."""
    lines = []
    for protocol in dict.fromkeys(c.protocol for c in cells):
        pc = [c for c in cells if c.protocol == protocol]
        profile = ", ".join(dict.fromkeys(c.limit_profile for c in pc))
        lines.append(f"### Closed loop, protocol `{protocol}` (limit profile: {profile})\n")
        lines.append(
            "| n_train | obs ratio | observed | task | hand-over err [cm] closed loop | one-shot "
            "| final err [cm] | arrival delay [s] | max limit ratio | refused / re-plans | collisions |"
        )
        lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
        for c in pc:
            lines.append(
                f"| {c.n_train} | {c.obs_ratio:g} | {observe_key(c.observe)} | {c.task} "
                f"| {_fmt(c.closed_loop_handover_error_cm)} | {_fmt(c.one_shot_handover_error_cm)} "
                f"| {_fmt(c.closed_loop_final_error_cm)} | {_fmt(c.arrival_delay_s)} "
                f"| {_fmt(c.max_limit_ratio, 3)} | {c.refused_replans} / {c.replans} | {c.collisions} |"
            )
        lines.append("")
        for key in dict.fromkeys(observe_key(c.observe) for c in pc):
            kc = [c for c in pc if observe_key(c.observe) == key]
            below = sum(
                1
                for c in kc
                if c.closed_loop_handover_error_cm is not None
                and c.one_shot_handover_error_cm is not None
                and c.closed_loop_handover_error_cm < c.one_shot_handover_error_cm
            )
            lines.append(
                f"- {key}, median over {len(kc)} cells: hand-over error "
                f"{_fmt(_median([c.closed_loop_handover_error_cm for c in kc]))} cm closed loop vs "
                f"{_fmt(_median([c.one_shot_handover_error_cm for c in kc]))} cm one-shot (closed loop "
                f"below one-shot in {below} of {len(kc)} cells); final error "
                f"{_fmt(_median([c.closed_loop_final_error_cm for c in kc]))} cm; arrival delay "
                f"{_fmt(_median([c.arrival_delay_s for c in kc]))} s; max limit ratio "
                f"{_fmt(max((c.max_limit_ratio or 0.0) for c in kc), 3)}; collisions "
                f"{sum(c.collisions for c in kc)}; refused re-plans {sum(c.refused_replans for c in kc)} "
                f"of {sum(c.replans for c in kc)}"
            )
        lines.append("")
    return "\n".join(lines)


def write_closed_loop_results(
    cells: Sequence[ClosedLoopCell], json_path: Path | None, md_path: Path | None, meta: dict
) -> None:
    """Write the JSON (the evaluation format, cells with the closed-loop fields) and the Markdown
    (the closed-loop table, then the usual recognition and prediction tables), each atomically."""
    if json_path is not None:
        atomic.write_text(json_path, json.dumps(to_json(cells, meta), indent=1, allow_nan=False))
    if md_path is not None:
        atomic.write_text(md_path, closed_loop_markdown(cells) + "\n" + to_markdown(cells))
