"""Recordings planned in a batch: every recording of a list planned with one trained model, its files
in a sub-folder of its own, and a summary (:mod:`.summary`).

A recording is any file or folder :func:`ipromp_pin.readers.expand_recordings` finds (multimodal CSV,
ROS 1 bag, rosbag2, native, chen2017 export), with no task label. Each is planned as
:func:`~.handover.plan` plans an observation: its observed window
(:class:`~ipromp_pin.data.ObservationWindow`) is all the planner sees; when the recording goes on
past the window and holds the robot, the plan is also scored against it
(:meth:`~.handover.HandoverPlan.scored`). A recording that cannot be read, or that lacks what the
model observes, is reported in the summary and does not stop the batch.

The recordings run as jobs of :mod:`ipromp_pin.evaluation.jobs`: in this process, in forked worker
processes (``jobs``), or on a Dask cluster (:class:`~ipromp_pin.evaluation.dask_cluster.DaskCluster`);
the outputs do not depend on where a recording ran.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from threadpoolctl import threadpool_limits

from ..data import GRIPPER, ROBOT, Demo, ObservationWindow
from ..evaluation.jobs import JobRunner, runner_of
from ..exceptions import DataError, InfeasibleError, UnreachableError
from ..planning.transfer import source_robot
from ..promp import IProMP
from ..readers import expand_recordings
from ..readers.recordings import recording_name
from ..robot import Robot
from ..robot.objects import ObjectTable
from ..robot.recordings import read_recording_for
from ..safety import CheckSuite
from .handover import HandoverPlan, plan
from .warnings import held_out_warning

STATUSES = ("passed", "failed", "unreadable")
"""A recording's status: planned and every check passed; planned, or tried, and a check (or the
timing) failed; not planned (unreadable, or lacking what the model observes)."""


@dataclass(frozen=True)
class PlanOptions:
    """How every recording of a batch is read, planned and written.

    Attributes:
        window: The observed part of each recording.
        frames: Skeleton frames to read (None: the reader's defaults).
        rate_hz: The rate the recordings are resampled to [Hz] (the model's training rate).
        control_rate_hz: The trajectories' control rate [Hz].
        retreat: Plan the retreat after the hand-over where the task's object has one.
        score: Score a plan against its recording when the recording goes on past the window.
        preview: Write each plan's preview page.
        ros: ROS version of ``trajectory.json``'s field names (1 or 2).
        rosbag: Write each plan's rosbag2 folder.
        ros1_bag: Also write each plan's ROS 1 bag.
        allow_failing_checks: Write a failing plan's trajectory, marked.
    """

    window: ObservationWindow = field(default_factory=ObservationWindow)
    frames: tuple[str, ...] | None = None
    rate_hz: float = 50.0
    control_rate_hz: float = 100.0
    retreat: bool = True
    score: bool = True
    preview: bool = False
    ros: int = 2
    rosbag: bool = True
    ros1_bag: bool = False
    allow_failing_checks: bool = False


@dataclass(frozen=True)
class RecordingJob:
    """One recording of a batch.

    Attributes:
        index: Its position in the batch.
        recording: Its path.
        out_dir: The sub-folder its files go to.
        problem: Why it cannot be planned, found before it ran (None: try it).
    """

    index: int
    recording: Path
    out_dir: Path
    problem: str | None = None


@dataclass
class PlannedRecording:
    """One recording's line of the summary.

    Attributes:
        index: Its position in the batch.
        recording: Its path.
        status: One of :data:`STATUSES`.
        out_dir: Its sub-folder (None: nothing written).
        task: The recognised task (None: not planned).
        posterior: That task's posterior probability.
        known: Whether the observation was recognised as one of the model's tasks (None: not planned).
        novelty_p_value: Its conformal novelty p-value (None: not planned, or no novelty detector).
        failures: The failed checks (``timing``, ``retreat.<check>``).
        observed_until_s: The end of the observed window [s] from the recording's start.
        arrival: When the human (predicted) and the robot reach the hand-over [s], and the delay.
        handover_error_cm: The planned vs the recorded gripper position at the recording's end [cm]
            (None: not scored).
        warnings: One line each.
        error: Why it was not planned, or why the planning failed (one line).
        files: Report key -> path of every file written.
    """

    index: int
    recording: str
    status: str
    out_dir: str | None = None
    task: str | None = None
    posterior: float | None = None
    known: bool | None = None
    novelty_p_value: float | None = None
    failures: list[str] = field(default_factory=list)
    observed_until_s: float | None = None
    arrival: dict[str, float | bool] | None = None
    handover_error_cm: float | None = None
    warnings: list[str] = field(default_factory=list)
    error: str | None = None
    files: dict[str, str] = field(default_factory=dict)

    def line(self) -> str:
        """One line for the console and logs."""
        if self.status == "unreadable":
            return f"{self.recording}: not planned: {self.error}"
        if self.task is None:
            return f"{self.recording}: FAILED: {self.error}"
        verdict = "passed" if self.status == "passed" else f"FAILED ({', '.join(self.failures)})"
        if self.known is False:
            verdict = f"UNKNOWN task: {self.error}"
        text = f"{self.recording}: {self.task} (posterior {self.posterior:.3f}), {verdict}"
        if self.arrival is not None:
            a = self.arrival
            when = "after" if a["delay_s"] >= 0 else "before"
            text += f", robot at rest {a['robot_s']:.2f} s ({abs(a['delay_s']):.2f} s {when} the human)"
        return text + (f" -> {self.out_dir}" if self.out_dir else "")


class PlanWorker:
    """Plans one recording of a batch (a :class:`~ipromp_pin.evaluation.jobs.Worker`): the model,
    the robot, the objects and the options, and its check suite, built on its first recording."""

    def __init__(self, model: IProMP, robot: Robot, objects: ObjectTable, options: PlanOptions) -> None:
        self.model = model
        self.robot = robot
        self.objects = objects
        self.options = options
        self.suite: CheckSuite | None = None
        # the recordings are the model's robot's: the placement's source when the arm is retargeted
        self.recorded = source_robot(model, robot) or robot

    def __getstate__(self) -> dict:
        return {**self.__dict__, "suite": None}  # a suite is rebuilt where it runs

    def for_one_job(self) -> PlanWorker:
        """A worker that shares no check state with this one."""
        return PlanWorker(self.model, self.robot, self.objects, self.options)

    def run_job(self, job: RecordingJob) -> PlannedRecording:
        """Read, plan, score and write one recording (see the module docstring)."""
        if job.problem is not None:
            return PlannedRecording(job.index, str(job.recording), "unreadable", error=job.problem)
        try:
            recording, observation, notes = self.observe(job.recording)
        except DataError as exc:
            return PlannedRecording(job.index, str(job.recording), "unreadable", error=str(exc))
        if self.suite is None:
            self.suite = CheckSuite.build(self.robot)
        opts = self.options
        try:
            planned = plan(
                self.model,
                observation,
                self.robot,
                objects=self.objects,
                suite=self.suite,
                control_rate_hz=opts.control_rate_hz,
                retreat=opts.retreat,
            )
        except InfeasibleError as exc:
            return PlannedRecording(
                job.index,
                str(job.recording),
                "failed",
                failures=["unreachable" if isinstance(exc, UnreachableError) else "timing"],
                observed_until_s=float(observation.t[-1]),
                warnings=notes,
                error=str(exc),
            )
        planned.warnings = notes + planned.warnings
        recorded_side = ROBOT in recording.groups or GRIPPER in recording.groups
        scorable = opts.score and recorded_side and recording.t[-1] > observation.t[-1]
        if scorable:
            planned = planned.scored(recording)
        written = planned.write(
            job.out_dir,
            ros=opts.ros,
            rosbag=opts.rosbag,
            ros1_bag=opts.ros1_bag,
            preview=opts.preview,
            recording=recording if scorable else None,
            allow_failing_checks=opts.allow_failing_checks,
        )
        return summary_row(job, planned, {k: str(v) for k, v in written.files.items()})

    def observe(self, path: Path) -> tuple[Demo, Demo, list[str]]:
        """The recording at ``path``, its observed window and the warnings about them.

        Raises:
            DataError: unreadable, or lacking a group the model observes.
        """
        opts = self.options
        recording = read_recording_for(path, self.recorded, frames=opts.frames, rate_hz=opts.rate_hz)
        missing = [g for g in self.model.observe_ if g not in recording.groups]
        if missing:
            raise DataError(
                recording.source,
                None,
                f"lacks {', '.join(missing)}, which the model observes "
                f"(it has {', '.join(recording.groups)})",
            )
        nominal = float(self.model.duration_nominal_s_)
        observation = opts.window.cut(recording, self.model.observe_, nominal)
        notes = []
        end = opts.window.end_s(nominal)
        if end is not None and recording.t[-1] - recording.t[0] < end:
            notes.append(
                f"{recording.name} ends at {recording.t[-1] - recording.t[0]:.2f} s, before the observed "
                f"window's end ({end:.2f} s): planned from all of it"
            )
        held = held_out_warning(self.model, recording, hint="plan recordings the model was not trained on")
        if held is not None and self.model.trained_on_ is not None:
            notes.append(held)
        return recording, observation, notes


def summary_row(job: RecordingJob, planned: HandoverPlan, files: dict[str, str]) -> PlannedRecording:
    """The summary line of a planned recording."""
    scores = planned.scores
    return PlannedRecording(
        job.index,
        str(job.recording),
        "passed" if planned.passed else "failed",
        out_dir=str(job.out_dir),
        task=planned.task,
        posterior=planned.posterior[planned.task],
        known=planned.known,
        novelty_p_value=planned.novelty_p_value,
        failures=planned.failures,
        error=None if planned.known else planned.approach.prediction.unknown_reason,
        observed_until_s=float(planned.observation.t[-1]),
        arrival=planned.arrival,
        handover_error_cm=None if scores is None else scores.handover_error_cm,
        warnings=list(planned.warnings),
        files=files,
    )


def folder_names(recordings: Sequence[Path]) -> list[str]:
    """A distinct sub-folder name per recording: its name (:func:`~ipromp_pin.readers.recordings.
    recording_name`: a stamp, a bag's or a folder's name), prefixed by its parent folder's name where
    two recordings share it, numbered where they still do."""

    def base(path: Path) -> str:
        try:
            return recording_name(path)
        except DataError:  # reported by its job
            return path.name

    def name(path: Path, depth: int) -> str:
        parts = [base(path)]
        parent = path.parent if parts[0] != path.parent.name else path.parent.parent
        while len(parts) <= depth and parent.name:
            if parent.name != "csv":  # the chen2017 and multimodal exports' own folder
                parts.insert(0, parent.name)
            parent = parent.parent
        return re.sub(r"[^A-Za-z0-9._-]+", "_", "_".join(parts)).strip("._") or "recording"

    names = [name(p, 0) for p in recordings]
    clash = {n for n in names if names.count(n) > 1}
    names = [name(p, 1) if n in clash else n for p, n in zip(recordings, names, strict=True)]
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n}_{seen[n]}")
    return out


def batch_jobs(paths: Sequence[str | Path], out_dir: Path) -> list[RecordingJob]:
    """One job per recording that ``paths`` hold (a path that holds none, or is not there, is one
    job that reports it), each with its own sub-folder of ``out_dir``."""
    found: list[tuple[Path, str | None]] = []
    for p in paths:
        try:
            found += [(r, None) for r in expand_recordings([p])]
        except DataError as exc:
            found.append((Path(p), str(exc)))
    unique = list(dict.fromkeys(found))
    names = folder_names([r for r, _ in unique])
    return [
        RecordingJob(i, r, out_dir / n, problem)
        for i, ((r, problem), n) in enumerate(zip(unique, names, strict=True))
    ]


def plan_batch(
    worker: PlanWorker,
    work: Sequence[RecordingJob],
    jobs: int | JobRunner = 1,
    progress: Callable[[int, int, PlannedRecording], None] | None = None,
) -> list[PlannedRecording]:
    """Every recording of ``work`` planned by ``worker`` (:meth:`PlanWorker.run_job`) on ``jobs``
    (local worker processes, or a runner such as a Dask cluster); ``progress(done, total, row)``
    after each. Returns the summary lines in the batch's order."""
    rows: dict[int, PlannedRecording] = {}
    with threadpool_limits(limits=1, user_api="blas"):  # as in the worker processes: the same numbers
        for row in runner_of(jobs).run(worker, list(work)):
            rows[row.index] = row
            if progress is not None:
                progress(len(rows), len(work), row)
    return [rows[job.index] for job in work]
