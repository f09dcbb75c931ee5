"""What the previews show of the arm's dynamics: the joints' torque usage and the object in the gripper.

:func:`torque_preview` turns a timed robot motion and what the checks know (the task, its object, the
hand-over time) into the preview's plain arrays (:class:`~ipromp_pin.preview.torques.TorqueTrack`,
:class:`~ipromp_pin.preview.torques.HeldObject`). The torques are the joint-torque check's own
(:meth:`~ipromp_pin.safety.joint_torques.JointTorques.torques`, computed once: a trajectory
whose ``effort_nm`` the pipeline has already filled in is not computed again), with the object
attached while the robot holds it (``robot_gives``: until the hand-over; ``robot_receives``: from it
on), so that the bars' peak is the check's ``peak_torque_ratio`` (the check evaluates a subsample of a
long motion: the bars' peak is then at least the check's).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..motion.trajectory import Trajectory
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from ..preview.torques import HeldObject, TorqueTrack
from ..robot import Robot
from ..robot.objects import ObjectTable, TaskObject
from ..safety import CheckContext
from ..safety.joint_torques import JointTorques

__all__ = [
    "SPHERE_RADIUS_M",
    "held_object",
    "payload_label",
    "plan_torques",
    "torque_preview",
    "torque_track",
]

SPHERE_RADIUS_M = 0.02
"""Radius [m] of the sphere drawn for an object whose task file gives no shape."""


def payload_label(payload: TaskObject | None) -> str:
    """How the panel names the payload: ``"spanner_handover (0.25 kg)"``, "" for none."""
    return "" if payload is None or payload.mass_kg <= 0 else f"{payload.task} ({payload.mass_kg:g} kg)"


def torque_track(
    check: JointTorques, motion: Trajectory, context: CheckContext, tau_nm: np.ndarray | None = None
) -> TorqueTrack:
    """The torque usage of ``motion`` (on the human's clock); ``tau_nm`` (N, n_joints) [N m]: its
    torques when already computed by ``check.torques(motion, context)`` (the trajectory's
    ``effort_nm``), else they are computed here."""
    tau = check.torques(motion, context) if tau_nm is None else np.asarray(tau_nm, dtype=float)
    limit = check.dynamics.effort_limit_nm
    payload = context.task_object()
    if payload is None or payload.mass_kg <= 0:
        held = np.zeros(motion.n_samples, dtype=bool)
    else:
        held = payload.held_at(motion.t_s, context.handover_time(motion.t_s))
    return TorqueTrack(
        t_s=motion.t_s,
        ratio=np.abs(tau) / limit,
        joint_names=check.robot.joint_names,
        limit_nm=limit,
        allowed_ratio=1.0 - check.robot.settings.effort_margin,
        held=held,
        payload=payload_label(payload),
    )


def held_object(robot: Robot, payload: TaskObject | None, handover_s: float) -> HeldObject | None:
    """The object drawn in the gripper (the dynamics' gripper frame, ``ee_parent_frame``): its task
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
        center_m=np.asarray(payload.com_m, dtype=float),
        axis=axis,
        held_from_s=None if gives else handover_s,
        held_until_s=handover_s if gives else None,
    )


def torque_preview(
    robot: Robot,
    motion: Trajectory,
    context: CheckContext,
    tau_nm: np.ndarray | None = None,
    check: JointTorques | None = None,
) -> tuple[TorqueTrack | None, HeldObject | None]:
    """The torque track and the held object of ``motion`` (on the human's clock) in ``context`` (the
    task, the objects, the hand-over time; the check's hand-over time when it has none). ``check``:
    the session's joint-torque check (None: one is made for ``robot``)."""
    if motion.n_samples == 0:
        return None, None
    torques = check if check is not None else JointTorques(robot)
    track = torque_track(torques, motion, context, tau_nm)
    return track, held_object(robot, context.task_object(), context.handover_time(motion.t_s))


def plan_torques(
    result: PlanResult,
    robot: Robot,
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
) -> tuple[TorqueTrack | None, HeldObject | None]:
    """:func:`torque_preview` of a planned hand-over as its joint-torque check saw it: the trajectory
    (on the human's clock), the recognised task's object in ``objects``, the hand-over when both the
    human (predicted) and the robot are there, the trajectory's ``effort_nm`` if any. A checked
    ``retreat`` (its ``effort_nm`` filled in) continues the track after the hand-over, with the
    object held as after the hand-over."""
    tr = result.trajectory
    p = result.prediction
    context = CheckContext(task=p.task, objects=objects, handover_s=float(p.duration_s))
    track, held = torque_preview(robot, tr, context, tr.effort_nm)
    if track is None or retreat is None:
        return track, held
    rt = retreat.trajectory
    if rt.effort_nm is None or rt.n_samples < 2:
        return track, held
    payload = context.task_object()
    carried = payload is not None and payload.mass_kg > 0 and payload.holder == "robot_receives"
    n = rt.n_samples - 1  # the retreat's first sample is the hand-over itself
    track = replace(
        track,
        t_s=np.concatenate([track.t_s, rt.t_s[1:]]),
        ratio=np.vstack([track.ratio, np.abs(rt.effort_nm[1:]) / track.limit_nm]),
        held=np.concatenate([track.held, np.full(n, carried)]),
    )
    return track, held
