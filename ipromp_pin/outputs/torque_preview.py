"""What the previews show of the arm's dynamics: the joints' torque usage and the object in the gripper.

:func:`torque_preview` turns a timed robot motion and what the checks know (the task, its object, the
hand-over time) into the preview's plain arrays (:class:`~ipromp_pin.preview.torques.TorqueTrack`,
:class:`~ipromp_pin.preview.torques.HeldObject`). The torques are the joint-torque check's own, at
the samples it evaluates (:meth:`~ipromp_pin.safety.joint_torques.JointTorques.evaluated`: every
sample of a short motion, a subsample of a long one), with the object attached while the robot holds
it (``robot_gives``: until the hand-over; ``robot_receives``: from it on), so that the bars' peak is
the check's ``peak_torque_ratio`` at its time and each joint's the check's ``ratios``; the panel
states the report's figures themselves (:func:`torque_figures`, read from the verdicts).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np

from ..motion.trajectory import Trajectory
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from ..preview.reported import ReportedFigure
from ..preview.torques import HeldObject, TorqueTrack
from ..robot import Robot
from ..robot.objects import ObjectTable, TaskObject
from ..safety import CheckContext, Verdict
from ..safety.joint_torques import JointTorques, TorqueMeasures

__all__ = [
    "SPHERE_RADIUS_M",
    "held_object",
    "payload_label",
    "plan_torques",
    "torque_figures",
    "torque_preview",
    "torque_track",
]

SPHERE_RADIUS_M = 0.02
"""Radius [m] of the sphere drawn for an object whose task file gives no shape."""


def payload_label(payload: TaskObject | None) -> str:
    """How the panel names the payload: ``"spanner_handover (0.25 kg)"``, "" for none."""
    return "" if payload is None or payload.mass_kg <= 0 else f"{payload.task} ({payload.mass_kg:g} kg)"


def torque_track(
    check: JointTorques, motion: Trajectory, context: CheckContext, every_sample: bool = False
) -> TorqueTrack:
    """The torque usage of ``motion`` (on the human's clock) at the samples ``check`` evaluates in
    ``context`` (:meth:`~ipromp_pin.safety.joint_torques.JointTorques.evaluated`); ``every_sample``:
    at every sample instead (the motion's ``effort_nm`` when the pipeline filled it in, e.g. for the
    torque plot)."""
    if every_sample:
        idx = np.arange(motion.n_samples)
        tau = check.torques(motion, context) if motion.effort_nm is None else np.asarray(motion.effort_nm)
    else:
        idx, tau = check.evaluated(motion, context)
    limit = check.dynamics.effort_limit_nm
    payload = context.task_object()
    t = motion.t_s[idx]
    if payload is None or payload.mass_kg <= 0:
        held = np.zeros(idx.size, dtype=bool)
    else:
        held = payload.held_at(t, context.handover_time(motion.t_s))
    return TorqueTrack(
        t_s=t,
        ratio=np.abs(tau) / limit,
        joint_names=check.robot.joint_names,
        limit_nm=limit,
        allowed_ratio=1.0 - check.robot.settings.effort_margin,
        held=held,
        payload=payload_label(payload),
        samples="every control sample"
        if every_sample
        else f"the {idx.size} of {motion.n_samples} samples the {check.name} check evaluated",
    )


def torque_figures(verdicts: Iterable[Verdict], prefix: str = "") -> list[ReportedFigure]:
    """The report's figures of the joint-torque check among ``verdicts`` (``prefix``: how the check
    list names it, e.g. ``"retreat "``): its peak usage, with its joint, time and the verdict's reason."""
    return [
        ReportedFigure(prefix + v.name, m.peak_torque_ratio, m.t_s, v.reason, (m.joint,))
        for v in verdicts
        if isinstance(m := v.measures, TorqueMeasures)
    ]


def held_object(robot: Robot, payload: TaskObject | None, handover_s: float) -> HeldObject | None:
    """The object drawn in the gripper (the dynamics' gripper frame: ``ee_parent_frame``'s axes, at its
    gripper point, the ``[tool]``'s centre point when one is mounted): its task
    file's shape, else a small sphere at ``com_m``; held until ``handover_s`` [s] on the human's clock
    (``robot_gives``) or from it on (``robot_receives``). ``None`` without a payload."""
    if payload is None or payload.mass_kg <= 0:
        return None
    shape = payload.shape or {}
    kind = str(shape.get("kind", "sphere"))
    axis = 2
    if kind == "box":
        dims = [float(v) for v in shape["size_m"]]
    elif kind == "cylinder":
        dims = [float(shape["radius_m"]), float(shape["length_m"])]
        axis = "xyz".index(str(shape.get("axis", "z")))
    else:
        kind, dims = "sphere", [SPHERE_RADIUS_M]
    gives = payload.holder == "robot_gives"
    return HeldObject(
        name=payload.task,
        mass_kg=payload.mass_kg,
        frame=robot.settings.ee_parent_frame,
        kind=kind,
        dims_m=dims,
        center_m=robot.settings.gripper_point_m + np.asarray(payload.com_m, dtype=float),
        axis=axis,
        held_from_s=None if gives else handover_s,
        held_until_s=handover_s if gives else None,
    )


def torque_preview(
    robot: Robot,
    motion: Trajectory,
    context: CheckContext,
    check: JointTorques | None = None,
    reported: Sequence[ReportedFigure] = (),
    every_sample: bool = False,
) -> tuple[TorqueTrack | None, HeldObject | None]:
    """The torque track (:func:`torque_track`) and the held object of ``motion`` (on the human's
    clock) in ``context`` (the task, the objects, the hand-over time; the check's hand-over time when
    it has none). ``check``: the session's joint-torque check (None: one is made for ``robot``);
    ``reported``: the report's figures the panel states."""
    if motion.n_samples == 0:
        return None, None
    torques = check if check is not None else JointTorques(robot)
    track = replace(torque_track(torques, motion, context, every_sample), reported=tuple(reported))
    return track, held_object(robot, context.task_object(), context.handover_time(motion.t_s))


def plan_torques(
    result: PlanResult,
    robot: Robot,
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
    check: JointTorques | None = None,
    every_sample: bool = False,
) -> tuple[TorqueTrack | None, HeldObject | None]:
    """:func:`torque_preview` of a planned hand-over as its joint-torque check saw it: the trajectory
    (on the human's clock), the recognised task's object in ``objects``, the hand-over when both the
    human (predicted) and the robot are there. A ``retreat`` continues the track after the hand-over
    as its own check saw it (the object held as after the hand-over; its first sample, the
    hand-over, at the approach's last time). The panel states both verdicts' figures; ``every_sample``:
    see :func:`torque_track`."""
    tr = result.trajectory
    p = result.prediction
    torques = check if check is not None else JointTorques(robot)
    context = CheckContext(task=p.task, objects=objects, handover_s=float(p.duration_s))
    figures = torque_figures(result.checks)
    track, held = torque_preview(robot, tr, context, torques, figures, every_sample)
    if track is None or retreat is None or retreat.trajectory.n_samples < 2:
        return track, held
    after = context.replace(handover_s=retreat.start_s, after_handover=True)
    more = torque_track(torques, retreat.trajectory, after, every_sample)
    track = replace(
        track,
        t_s=np.concatenate([track.t_s, more.t_s]),
        ratio=np.vstack([track.ratio, more.ratio]),
        held=np.concatenate([track.held, more.held]),
        samples=f"approach: {track.samples}; retreat: {more.samples}",
        reported=(*figures, *torque_figures(retreat.checks, "retreat ")),
    )
    return track, held
