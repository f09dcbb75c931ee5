"""Content of a preview: everything one 3-D preview shows, validated, in plain arrays.

:class:`PreviewContent` holds the Pinocchio model handles plus plain arrays (robot trajectory,
predicted end-effector path and its spread, human hand path, task posterior, feasibility results),
so that the preview does not depend on the recognition or planning internals. All positions are in
[m] in the robot's base frame, times in [s] from the start of the motion. Bad input raises
:class:`~ipromp_pin.exceptions.DataError` naming the field.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from ..exceptions import DataError
from ..fields import float_array
from .body import BodyTrack, SeparationTrack
from .torques import HeldObject, TorqueTrack

__all__ = ["CHECK_STATUSES", "SOURCE", "FeasibilityCheck", "PreviewContent", "finite_array", "preview_error"]

#: ``source`` of every :class:`~ipromp_pin.exceptions.DataError` raised by the preview.
SOURCE = "preview"


def preview_error(field_name: str | None, problem: str) -> DataError:
    """Error about the preview input ``field_name`` (``source`` is :data:`SOURCE`)."""
    return DataError(SOURCE, field_name, problem)


def finite_array(value: Any, field_name: str, ndim: int, last: int | None = None) -> np.ndarray:
    """Finite float array with ``ndim`` dimensions (and last dimension ``last``).

    Raises:
        DataError: Not numeric, wrong shape, empty, or with NaN / infinite values.
    """
    return float_array(value, field_name, ndim, preview_error, last)


def _optional_array(value: Any, field_name: str, ndim: int, last: int | None = None) -> np.ndarray | None:
    return None if value is None else finite_array(value, field_name, ndim, last)


CHECK_STATUSES = ("pass", "fail", "skip", "info")
"""Statuses of a :class:`FeasibilityCheck`: ``"skip"`` is a check that could not be made (e.g. the
human hand position is unknown), drawn as skipped, neither passed nor failed; ``"info"`` is a line
that states a figure without judging it (e.g. a replay's refused re-plans, which are normal), drawn
neutrally."""


class FeasibilityCheck(NamedTuple):
    """One line of the feasibility panel.

    Attributes:
        name: Check name, e.g. ``"joint limits"``.
        passed: Whether the check passed (``True`` for a skipped check: it does not fail the plan).
        detail: Short detail, e.g. ``"left_e1 within 0.02 rad of its limit"``; times in it are on the
            page's one clock (the human's motion, as ``t_s``).
        status: One of :data:`CHECK_STATUSES` (``""``: ``"pass"`` or ``"fail"`` from ``passed``).
        required: Whether the check counts towards the verdict (``False``: advisory).
    """

    name: str
    passed: bool
    detail: str = ""
    status: str = ""
    required: bool = True


def _feasibility_check(item: object) -> FeasibilityCheck:
    """One ``PreviewContent.feasibility`` item, ``(name, passed[, detail[, status[, required]]])``,
    as a checked :class:`FeasibilityCheck`."""
    if not isinstance(item, (tuple, list)) or not 2 <= len(item) <= 5:
        raise preview_error("feasibility", f"expected (name, passed, detail, status, required), got {item!r}")
    name, passed = str(item[0]), bool(item[1])
    detail = str(item[2]) if len(item) > 2 else ""
    status = str(item[3]) if len(item) > 3 and item[3] else ("pass" if passed else "fail")
    if status not in CHECK_STATUSES:
        raise preview_error("feasibility", f"check '{name}': unknown status {status!r}")
    if (status == "fail") == passed:
        raise preview_error("feasibility", f"check '{name}': status {status!r} but passed={passed}")
    required = bool(item[4]) if len(item) > 4 else True
    return FeasibilityCheck(name, passed, detail, status, required)


@dataclass
class PreviewContent:
    """Everything one preview shows (built by the pipeline from the model and planner outputs).

    Attributes:
        model: Pinocchio model of the whole robot.
        visual_model: Visual geometry (meshes) of the robot; ``None`` draws ``collision_model``.
        t_s: (N,) times of the robot trajectory in [s] on the human's clock (t = 0 at the start of the
            human's motion; the robot rests at ``q[0]`` before ``t_s[0]``), strictly increasing.
        q: (N, J) arm joint positions in [rad] at ``t_s``.
        joint_names: (J,) model joint names of the columns of ``q``.
        q_full: (nq,) full configuration giving the other joints' fixed values (``None``: neutral).
        collision_model: Collision geometry (used when ``visual_model`` is ``None``).
        ee_mean: (M, 3) predicted end-effector path in [m] (mean).
        ee_samples: (S, M, 3) end-effector paths of trajectories sampled from the prediction.
        ee_std: (M, 3) per-point standard deviation of the end-effector path in [m]; computed
            from ``ee_samples`` when only those are given.
        ee_truth: (G, 3) recorded robot end-effector path (ground truth of a known demo).
        hand_path: (H, 3) human hand path in [m] in the robot base frame.
        hand_t_s: (H,) times of ``hand_path`` in [s] (animates a hand marker, splits the path
            at ``observed_until_s``).
        hand_observed_index: Number of ``hand_path`` points that were observed (overrides the
            split computed from ``hand_t_s`` and ``observed_until_s``).
        observed_until_s: End of the observed window in [s] from the start of the human's motion.
        human_duration_s: Duration of the human's whole motion in [s] (the recorded demo's, or the
            predicted one): the page shows the observed fraction of the HUMAN's motion.
        human_duration_source: Where ``human_duration_s`` comes from, e.g. ``"recorded"`` or
            ``"predicted"`` (named on the page).
        handover_point: (3,) hand-over point in [m].
        body: The human body's capsules over the recording (:class:`~.body.BodyTrack`, human's clock).
        separation: The robot-body separation per control sample (:class:`~.body.SeparationTrack`,
            human's clock).
        task: Recognised task name.
        tasks: (K,) names of all tasks.
        posterior: (K,) posterior probability of every task (sums to 1).
        feasibility: Feasibility results as :class:`FeasibilityCheck` or ``(name, passed, detail)``.
        collision_links: Links (frame or geometry names) found in collision: drawn red.
        near_limit_joints: Joints near a limit: the link they move is drawn orange.
        title: Title of the page / panel.
        notes: Lines shown in the panel below the time base (e.g. when the human and the robot arrive).
        timebase: One line saying what the page's clock is ("": the human's motion, t = 0 at its start).
        label_prefix: Text before the task in the 3-D label (e.g. ``"final task: "`` for a replay,
            whose panel follows the re-plans while the label is fixed).
        torques: The joints' torque usage per control sample (:class:`~.torques.TorqueTrack`, human's
            clock): bars in the panel.
        held_object: The task's object (:class:`~.torques.HeldObject`): drawn in the gripper while held.
    """

    model: pin.Model
    visual_model: pin.GeometryModel | None
    t_s: np.ndarray
    q: np.ndarray
    joint_names: Sequence[str]
    q_full: np.ndarray | None = None
    collision_model: pin.GeometryModel | None = None
    ee_mean: np.ndarray | None = None
    ee_samples: np.ndarray | None = None
    ee_std: np.ndarray | None = None
    ee_truth: np.ndarray | None = None
    hand_path: np.ndarray | None = None
    hand_t_s: np.ndarray | None = None
    hand_observed_index: int | None = None
    observed_until_s: float | None = None
    human_duration_s: float | None = None
    human_duration_source: str = ""
    handover_point: np.ndarray | None = None
    body: BodyTrack | None = None
    separation: SeparationTrack | None = None
    task: str = ""
    tasks: Sequence[str] = ()
    posterior: np.ndarray | None = None
    feasibility: Sequence[FeasibilityCheck | tuple] = ()
    collision_links: Sequence[str] = ()
    near_limit_joints: Sequence[str] = ()
    title: str = "ipromp_pin preview"
    notes: Sequence[str] = ()
    timebase: str = ""
    label_prefix: str = ""
    torques: TorqueTrack | None = None
    held_object: HeldObject | None = None
    _q_index: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._check_motion()
        self._check_prediction()
        self._check_human()
        self._check_recognition()
        self.feasibility = tuple(_feasibility_check(item) for item in self.feasibility)
        self._check_highlights()

    def _check_motion(self) -> None:
        """The model, the trajectory (``t_s``, ``q``, ``joint_names``) and ``q_full``."""
        if not isinstance(self.model, pin.Model):
            raise preview_error("model", f"expected a pinocchio.Model, got {type(self.model).__name__}")
        if self.visual_model is None and self.collision_model is None:
            raise preview_error("visual_model", "neither a visual nor a collision model was given")
        self.t_s = finite_array(self.t_s, "t_s", 1)
        if self.t_s.size >= 2 and np.any(np.diff(self.t_s) <= 0.0):
            raise preview_error("t_s", "times must be strictly increasing")
        self.joint_names = tuple(str(n) for n in self.joint_names)
        self.q = finite_array(self.q, "q", 2, len(self.joint_names))
        if self.q.shape[0] != self.t_s.size:
            raise preview_error("q", f"has {self.q.shape[0]} rows but t_s has {self.t_s.size} samples")
        index = []
        for name in self.joint_names:
            if not self.model.existJointName(name):
                raise preview_error("joint_names", f"joint '{name}' is not in the robot model")
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq != 1:
                raise preview_error(
                    "joint_names", f"joint '{name}' has {joint.nq} configuration variables, expected 1"
                )
            index.append(joint.idx_q)
        self._q_index = np.asarray(index, dtype=int)
        if self.q_full is None:
            self.q_full = pin.neutral(self.model)
        self.q_full = finite_array(self.q_full, "q_full", 1)
        if self.q_full.size != self.model.nq:
            raise preview_error(
                "q_full", f"expected {self.model.nq} values (model.nq), got {self.q_full.size}"
            )

    def _check_prediction(self) -> None:
        """The predicted end-effector path: ``ee_mean``, ``ee_samples``, ``ee_std``, ``ee_truth``."""
        self.ee_mean = _optional_array(self.ee_mean, "ee_mean", 2, 3)
        self.ee_samples = _optional_array(self.ee_samples, "ee_samples", 3, 3)
        self.ee_std = _optional_array(self.ee_std, "ee_std", 2, 3)
        if self.ee_samples is not None:
            if self.ee_mean is None:
                self.ee_mean = self.ee_samples.mean(axis=0)
            if self.ee_samples.shape[1] != self.ee_mean.shape[0]:
                raise preview_error(
                    "ee_samples",
                    f"paths have {self.ee_samples.shape[1]} points, ee_mean has {self.ee_mean.shape[0]}",
                )
            if self.ee_std is None and self.ee_samples.shape[0] >= 2:
                self.ee_std = self.ee_samples.std(axis=0, ddof=1)
        if self.ee_std is not None:
            if self.ee_mean is None:
                raise preview_error("ee_std", "given without ee_mean")
            if self.ee_std.shape != self.ee_mean.shape:
                raise preview_error(
                    "ee_std", f"shape {self.ee_std.shape} differs from ee_mean {self.ee_mean.shape}"
                )
            if np.any(self.ee_std < 0.0):
                raise preview_error("ee_std", "standard deviations must be >= 0")
        self.ee_truth = _optional_array(self.ee_truth, "ee_truth", 2, 3)

    def _check_human(self) -> None:
        """The human's side: hand path and times, observed window, duration, hand-over point."""
        self.hand_path = _optional_array(self.hand_path, "hand_path", 2, 3)
        self.hand_t_s = _optional_array(self.hand_t_s, "hand_t_s", 1)
        if self.hand_t_s is not None:
            if self.hand_path is None:
                raise preview_error("hand_t_s", "given without hand_path")
            if self.hand_t_s.size != self.hand_path.shape[0]:
                raise preview_error(
                    "hand_t_s", f"has {self.hand_t_s.size} samples, hand_path has {self.hand_path.shape[0]}"
                )
            if self.hand_t_s.size >= 2 and np.any(np.diff(self.hand_t_s) <= 0.0):
                raise preview_error("hand_t_s", "times must be strictly increasing")
        if self.hand_observed_index is not None:
            if self.hand_path is None:
                raise preview_error("hand_observed_index", "given without hand_path")
            idx = int(self.hand_observed_index)
            if not 0 <= idx <= self.hand_path.shape[0]:
                raise preview_error("hand_observed_index", f"{idx} outside [0, {self.hand_path.shape[0]}]")
            self.hand_observed_index = idx
        if self.observed_until_s is not None:
            self.observed_until_s = float(self.observed_until_s)
            if not np.isfinite(self.observed_until_s) or self.observed_until_s < 0.0:
                raise preview_error(
                    "observed_until_s", f"must be a finite time >= 0, got {self.observed_until_s}"
                )
        if self.human_duration_s is not None:
            self.human_duration_s = float(self.human_duration_s)
            if not np.isfinite(self.human_duration_s) or self.human_duration_s <= 0.0:
                raise preview_error(
                    "human_duration_s", f"must be a finite duration > 0, got {self.human_duration_s}"
                )
        self.human_duration_source = str(self.human_duration_source)
        self.handover_point = _optional_array(self.handover_point, "handover_point", 1, 3)
        kinds = (("body", BodyTrack), ("separation", SeparationTrack), ("torques", TorqueTrack))
        for name, kind in (*kinds, ("held_object", HeldObject)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise preview_error(name, f"expected a {kind.__name__}, got {type(value).__name__}")
        if self.held_object is not None and not self.model.existFrame(self.held_object.frame):
            raise preview_error("held_object", f"frame '{self.held_object.frame}' is not in the robot model")

    def _check_recognition(self) -> None:
        """The recognised ``task`` among ``tasks`` and their ``posterior``."""
        self.tasks = tuple(str(t) for t in self.tasks)
        self.task = str(self.task)
        if self.posterior is not None:
            self.posterior = finite_array(self.posterior, "posterior", 1)
            if self.posterior.size != len(self.tasks):
                raise preview_error(
                    "posterior", f"has {self.posterior.size} values for {len(self.tasks)} tasks"
                )
            if np.any(self.posterior < 0.0) or abs(float(self.posterior.sum()) - 1.0) > 1e-6:
                raise preview_error("posterior", "must be probabilities >= 0 summing to 1")
        if self.task and self.tasks and self.task not in self.tasks:
            raise preview_error("task", f"'{self.task}' is not one of the tasks {list(self.tasks)}")

    def _check_highlights(self) -> None:
        """The links drawn red (``collision_links``) and the joints drawn orange (``near_limit_joints``)."""
        self.collision_links = tuple(str(n) for n in self.collision_links)
        for name in self.collision_links:
            self.link_frame(name)
        self.near_limit_joints = tuple(str(n) for n in self.near_limit_joints)
        for name in self.near_limit_joints:
            if not self.model.existJointName(name):
                raise preview_error("near_limit_joints", f"joint '{name}' is not in the robot model")

    def link_frame(self, name: str) -> int:
        """Frame id of a link given by its frame name or by a geometry object's name."""
        if self.model.existFrame(name):
            return self.model.getFrameId(name)
        for geometry in (self.collision_model, self.visual_model):
            if geometry is not None and geometry.existGeometryName(name):
                return geometry.geometryObjects[geometry.getGeometryId(name)].parentFrame
        raise preview_error("collision_links", f"'{name}' is neither a frame nor a geometry of the robot")

    @property
    def checks(self) -> tuple[FeasibilityCheck, ...]:
        """The feasibility results as checked :class:`FeasibilityCheck` lines."""
        return tuple(
            c if isinstance(c, FeasibilityCheck) else _feasibility_check(c) for c in self.feasibility
        )

    @property
    def duration_s(self) -> float:
        """The robot trajectory's last time in [s] on the human's clock (it rests before ``t_s[0]``)."""
        return float(self.t_s[-1])

    @property
    def end_s(self) -> float:
        """The page's last time in [s] on the human's clock: the latest last sample of the robot's
        trajectory, the hand path, the body, the separation and the torques (the animation ends
        there, and never later)."""
        tracks = (
            self.hand_t_s,
            *(None if x is None else x.t_s for x in (self.body, self.separation, self.torques)),
        )
        return max([self.duration_s] + [float(t[-1]) for t in tracks if t is not None])

    def observed_fraction(self) -> float | None:
        """Observed fraction of the human's motion (``observed_until_s / human_duration_s``, at most 1),
        ``None`` when either is unknown; never relative to the robot trajectory's duration."""
        if self.observed_until_s is None or self.human_duration_s is None:
            return None
        return min(1.0, self.observed_until_s / self.human_duration_s)

    def configurations(self, t_s: np.ndarray) -> np.ndarray:
        """Full configurations (len(t_s), nq) at times ``t_s`` [s], arm joints linearly interpolated."""
        assert self.q_full is not None  # set by __post_init__
        qs = np.repeat(self.q_full[None, :], len(t_s), axis=0)
        for j, iq in enumerate(self._q_index):
            qs[:, iq] = np.interp(t_s, self.t_s, self.q[:, j])
        return qs

    def hand_observed_count(self) -> int | None:
        """Number of observed ``hand_path`` points, ``None`` when unknown."""
        if self.hand_path is None:
            return None
        if self.hand_observed_index is not None:
            return self.hand_observed_index
        if self.hand_t_s is not None and self.observed_until_s is not None:
            return int(np.searchsorted(self.hand_t_s, self.observed_until_s, side="right"))
        return None

    def replace(self, **changes: Any) -> PreviewContent:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)
