"""What the preview pages show: a planned hand-over (``run``, ``preview``) and a replay's timeline.

:func:`preview_content` is the :class:`~ipromp_pin.preview.PreviewContent` of a planned hand-over
(rendered by :func:`~ipromp_pin.preview.render_html` or shown live); :func:`replay_preview_html` is
the time-scrubbing ``preview.html`` of a replay (:mod:`ipromp_pin.preview.timeline`).

The pages show the report's figures: the check list is the verdicts (each with its time, the
report's ``t_s``), the separation and torque panels state the verdicts of ``human_clearance``,
``contact_speed`` and ``joint_torques`` and draw the checks' own per-sample measures for the human
and the motions they judged (:mod:`.human_preview`, :mod:`.torque_preview`). One clock: every time
is on the human's motion (t = 0 at its start).
"""

from __future__ import annotations

import math

import numpy as np

from ..data import ROBOT, Demo
from ..evaluation.scoring import ClosedLoopScore
from ..human import HumanMotion
from ..motion.trajectory import Trajectory
from ..planning.closed_loop import ClosedLoopResult
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from ..preview import PreviewContent
from ..preview.timeline import TimelineEvent, render_timeline_html
from ..robot import Robot, ee_positions, frame_placements
from ..robot.objects import ObjectTable
from ..robot.rotations import geodesic_deg
from ..safety import CheckContext, CheckReport, Verdict
from ..safety.joint_limits import JointLimitMeasures
from ..safety.self_collision import SelfCollisionMeasures
from .human_preview import human_label, human_tracks, judged_human, separation_figures
from .replay_report import unknown_lines
from .report import arrival_line, orientation_line
from .torque_preview import plan_torques, torque_figures, torque_preview


def preview_content(
    result: PlanResult,
    robot: Robot,
    demo: Demo | None,
    visual_model: object = None,
    human: HumanMotion | None = None,
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
) -> PreviewContent:
    """The :class:`~ipromp_pin.preview.PreviewContent` of a planned hand-over.

    The body drawn, and the plan's separation from it, is ``human``: the human the checks judged
    (the plan's context's: as observed until the end of the observation, then held; None: the robot
    settings' assumed human, as the checks take a context without one). The separation panel states
    the human checks' verdicts and draws ``human_clearance``'s measure per sample; the torque panel
    states the joint-torque verdicts and draws the torques at the samples the check evaluated (the
    recognised task's object in ``objects``, the hand-over at the trajectory's end). ``demo``: the
    recording (the recorded robot and hand paths, the human's recorded duration). A ``retreat`` is
    animated after the hand-over (its frames appended, its torques after the approach's, its checks
    listed and stated as ``retreat <check>``)."""
    p = result.prediction
    tr = with_retreat(result.trajectory, retreat)  # on the human's clock
    checks = result.checks
    later = [] if retreat is None else list(retreat.checks)
    figures = separation_figures(checks) + separation_figures(later, "retreat ")
    body, separation = human_tracks(robot, tr, judged_human(robot, human), reported=figures)
    torques, held = plan_torques(result, robot, objects, retreat)
    ee_samples = np.stack([ee_positions(robot, s) for s in result.q_samples])
    truth = None
    hand = hand_t = None
    notes = [arrival_line(result)]
    if demo is not None and ROBOT in demo.groups:
        # the recording's joints are the model's robot's when the plan was retargeted to this arm
        recorded = robot if result.retarget is None else result.retarget.source
        truth, rot_true = frame_placements(recorded, demo.groups[ROBOT])
        rot_end = frame_placements(robot, result.trajectory.q[-1:])[1]
        notes.append(orientation_line(float(geodesic_deg(rot_end[0], rot_true[-1]))))
        if "hand_position" in demo.extras:
            hand, hand_t = demo.extras["hand_position"], demo.t
    failed = [v.measures for v in checks if not v.passed]
    collision_links = [link for m in failed if isinstance(m, SelfCollisionMeasures) for link in m.links]
    near_limit = [m.joint for m in failed if isinstance(m, JointLimitMeasures)]
    return PreviewContent(
        model=robot.model,
        visual_model=visual_model,
        collision_model=robot.collision_model,
        t_s=tr.t_s,  # the page's one clock: the human's
        q=tr.q,
        joint_names=robot.joint_names,
        q_full=robot.full_configuration(tr.q[0]),
        ee_mean=result.ee_path,
        ee_samples=ee_samples,
        ee_truth=truth,
        hand_path=hand,
        hand_t_s=hand_t,
        observed_until_s=p.observed_until_s,
        # the observed fraction is of the human's motion: the recorded demo's, else the predicted one
        human_duration_s=p.duration_s if demo is None else demo.duration_s,
        human_duration_source="predicted" if demo is None else "recorded",
        handover_point=result.handover_pose[:3],
        body=body,
        separation=separation,
        task=p.task,
        tasks=list(p.tasks),
        posterior=p.posterior,
        feasibility=[check_row(c) for c in checks] + [check_row(c, "retreat ") for c in later],
        collision_links=collision_links,
        near_limit_joints=near_limit,
        title=f"ipromp_pin: {p.task}" + ("" if demo is None else f" ({demo.task}/{demo.name})"),
        timebase=f"Times are on the human's motion (t = 0 at its start); the robot moves from "
        f"{result.trajectory.start_s:.2f} s to {result.trajectory.end_s:.2f} s",
        notes=notes + ([] if retreat is None else [retreat.to_text().splitlines()[0]]),
        torques=torques,
        held_object=held,
    )


def with_retreat(trajectory: Trajectory, retreat: RetreatResult | None) -> Trajectory:
    """``trajectory`` followed by the retreat's samples after its first (the hand-over itself);
    ``trajectory`` itself without a retreat."""
    return trajectory if retreat is None else trajectory.then(retreat.trajectory)


def check_row(v: Verdict, prefix: str = "") -> tuple[str, bool, str, str, bool]:
    """A row of the page's check list: the verdict's name (``prefix``: e.g. ``"retreat "``), whether
    it passed, its reason, status and whether it is required; a verdict whose measures have a time
    (the report's ``t_s``, on the human's clock) that its reason does not state gets it appended."""
    detail = v.reason
    t = getattr(v.measures, "t_s", None)
    if isinstance(t, int | float) and math.isfinite(t) and f"t={t:.2f} s" not in detail:
        detail += f" (t={t:.2f} s)"
    return (prefix + v.name, v.passed, detail, v.status, v.required)


def replay_preview_html(
    demo: Demo,
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    robot: Robot,
    visual_model: object,
    checks: CheckReport,
    human: HumanMotion | None = None,
    objects: ObjectTable | None = None,
    recorded_robot: Robot | None = None,
) -> str:
    """The time-scrubbing ``preview.html`` of a replay (one self-contained page; ``recorded_robot``:
    the robot the demo's joints are of when ``robot`` executed it retargeted, None: ``robot``).

    ``checks`` are the commanded motion's verdicts as the replay report judges it
    (:func:`~.replay_report.replay_checks`): the check list shows them after the closed loop's rows,
    the torque panel states the joint-torque verdict and draws the torques at its samples (the true
    task's object in ``objects``), and, when they hold the human checks, the separation panel states
    theirs and draws ``human_clearance``'s measure against ``human``, the human they judged (the
    recorded one). Without human verdicts (no tracked skeleton) the body and separation drawn are
    ``human``'s (e.g. the assumed one the closed loop planned with), labelled as not judged by the
    report."""
    traj = result.trajectory
    figures = separation_figures(checks)
    source = "" if human is None or figures else f"{human_label(human)}; not judged in report.json"
    body, separation = human_tracks(
        robot, traj, human, 1.0 / result.settings.control_rate_hz, reported=figures, source=source
    )
    context = CheckContext(task=demo.task, objects=objects)
    torques, held = torque_preview(robot, traj, context, reported=torque_figures(checks))
    tasks = list(result.replans[0].posterior) if result.replans else []
    committed = [r for r in result.replans if r.committed and not r.action]  # toward a hand-over
    hand = hand_t = None
    if "hand_position" in demo.extras:
        hp = demo.extras["hand_position"]
        ok = np.all(np.isfinite(hp), axis=1)
        if ok.sum() >= 2:
            hand, hand_t = hp[ok], (demo.t - demo.t[0])[ok]
    final = committed[-1] if committed else None
    content = PreviewContent(
        model=robot.model,
        visual_model=visual_model,
        collision_model=robot.collision_model,
        t_s=traj.t_s,
        q=traj.q,
        joint_names=robot.joint_names,
        q_full=robot.full_configuration(traj.q[0]),
        ee_mean=ee_positions(robot, traj.q[:: max(1, traj.n_samples // 200)]),
        ee_truth=ee_positions(recorded_robot or robot, demo.groups[ROBOT]),
        hand_path=hand,
        hand_t_s=hand_t,
        body=body,
        separation=separation,
        task=final.task if final else "",
        tasks=tasks,
        posterior=np.array([final.posterior[t] for t in tasks]) if final else None,
        feasibility=closed_loop_rows(result, score) + [check_row(c) for c in checks],
        title=f"ipromp_pin replay: {demo.task}/{demo.name}",
        timebase=f"Times are on the human's motion ({score.handover_time_s:.2f} s recorded, t = 0 at its "
        f"start); the robot starts at {result.start_s:.2f} s and comes to rest at {score.rest_s:.2f} s",
        label_prefix="final task: ",
        torques=torques,
        held_object=held,
    )
    summary = [
        f"Hand-over error {score.handover_error_cm:.1f} cm at the recorded hand-over time "
        f"({score.handover_time_s:.2f} s); {score.final_error_cm:.1f} cm at rest; gripper orientation "
        f"error {score.handover_orientation_error_deg:.1f} deg",
        f"Arrival {score.arrival_s:.2f} s vs recorded {score.recorded_arrival_s:.2f} s "
        f"(delay {score.arrival_delay_s:+.2f} s); {result.profile.name} limits",
        "Blue: commanded gripper path; cyan: the latest plan; purple: recorded robot; green: hand observed.",
        *unknown_lines(result),
    ]
    events = timeline_events(result, robot, tasks)
    return render_timeline_html(content, events, motion_s=score.handover_time_s, summary=summary)


def closed_loop_rows(result: ClosedLoopResult, score: ClosedLoopScore) -> list[tuple]:
    """The replay's check-list rows of the closed loop: re-plans, limits, collisions. The re-plans row
    states its counts neutrally (a refused re-plan keeps the committed plan: it is normal); it fails
    only when no re-plan was committed (the robot never moved towards a hand-over: a failed replay)."""
    committed = result.n_committed > 0
    replans = f"{result.n_committed} committed, {score.refused_replans} refused"
    if score.refused_replans and committed:
        replans += " (a refused re-plan keeps the committed plan)"
    return [
        ("re-plans", committed, replans, "info" if committed else "fail", True),
        (
            "limits",
            score.max_limit_ratio <= 1 + 1e-6,
            f"max ratio {score.max_limit_ratio:.3f} ({result.profile.name})",
        ),
        ("collisions", score.collisions == 0, f"{score.collisions} commanded samples in contact"),
    ]


ACTION_WORDS = {
    "stop": "stop on an unknown task (jerk-limited, then hold at rest)",
    "retreat": "retreat to the rest configuration (the task still unknown after the hold)",
}
"""How the preview's panel names a re-plan's :attr:`~ipromp_pin.planning.closed_loop.Replan.action`."""


def timeline_events(result: ClosedLoopResult, robot: Robot, tasks: list[str]) -> list[TimelineEvent]:
    """The re-plans of a replay as the timeline shows them (times on the human's clock), each
    committed one with its planned gripper path."""
    plans = iter(result.plans)
    events = []
    for r in result.replans:
        path_m = None
        if r.committed:
            q = next(plans).q
            path_m = ee_positions(robot, q[:: max(1, q.shape[0] // 40)])
        events.append(
            TimelineEvent(
                t_s=r.t_s,
                observed_until_s=r.observed_until_s,
                task=r.task,
                posterior=[r.posterior[t] for t in tasks] if r.posterior else [],
                predicted_handover_s=r.predicted_handover_s,
                handover_point=None
                if r.predicted_handover_position_m is None
                else np.asarray(r.predicted_handover_position_m),
                planned_path=path_m if path_m is not None and path_m.shape[0] >= 2 else None,
                arrival_s=r.planned_arrival_s,
                committed=r.committed,
                reason=r.reason,
                action=ACTION_WORDS.get(r.action, r.action),
            )
        )
    return events
