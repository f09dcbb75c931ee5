"""The run's figures: the conditioned prediction, the phase posterior, the learned distributions and,
with the robot, the timed trajectory against its limits, its separation from the human and its joint
torques (their numbers: :mod:`ipromp_pin.outputs.plot_series`).

:func:`write_plots` draws them with :mod:`ipromp_pin.outputs.plots` (imported when it draws:
matplotlib is only needed with ``--plots``) into a folder or an output set.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Demo
from ..motion.trajectory import JointLimits, Trajectory
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from ..promp import IProMP
from ..robot import Robot
from ..robot.objects import ObjectTable
from ..safety import CheckContext
from ..signals.groups import group_unit
from .files import FILE_KEYS
from .plot_series import motion_series, separation_series
from .torque_preview import plan_torques


def write_plots(
    result: PlanResult,
    model: IProMP,
    demo: Demo,
    out_dir: Path | atomic.OutputSet,
    robot: Robot | None = None,
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
    context: CheckContext | None = None,
) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions (and, with
    ``robot``, :func:`robot_plots`: the timed trajectory against its limits, its separation from the
    human and its joint torques), written into a folder or staged in an
    :class:`~ipromp_pin.atomic.OutputSet` (then they appear at its commit). ``retreat``: the plan's
    retreat (drawn after the approach); ``context``: what the checks knew (the human, the limits)."""
    from . import plots  # deferred: matplotlib is only needed with --plots (about 0.4 s to import)

    if isinstance(out_dir, atomic.OutputSet):
        out = out_dir

        def target(name: str) -> Path:
            return out.stage(name)  # a temporary file, renamed into place by the set's commit

    else:

        def target(name: str) -> Path:
            return Path(out_dir) / name

    files = {}
    p = result.prediction
    files["plot_prediction"] = plots.plot_prediction(
        p.t,
        p.q_mean,
        np.sqrt(np.maximum(np.diagonal(p.q_cov, axis1=1, axis2=2), 0.0)),
        target("prediction.png"),
        truth_t_s=demo.t,
        q_truth=demo.groups.get(ROBOT),
        observed_until_s=p.observed_until_s,
        joint_names=list(p.joint_names),
        title=f"{p.task}: conditioned prediction vs recorded",
    )
    # The joint posterior log p(task, alpha | obs) = log p(task | obs) + log p(alpha | task, obs):
    # one scale for every task (each task's phase posterior alone is normalised on its own).
    files["plot_phase"] = plots.plot_phase_posterior(
        {t: p.phase_grid[k] for k, t in enumerate(p.tasks)},
        {t: p.log_posterior[k] + p.phase_log_post[k] for k, t in enumerate(p.tasks)},
        target("phase_posterior.png"),
        tasks=list(p.tasks),
        ylabel="log p(task, alpha | observation)",
        title="joint posterior of task and phase over the phase candidates",
    )
    z = np.linspace(0.0, 1.0, 100)
    _, std, _ = model.distribution(p.task, z)
    centre, lower, upper, labels = model.distribution_band(p.task, z, 2.0)
    files["plot_distributions"] = plots.plot_distributions(
        z,
        centre,
        std,
        target("distributions.png"),
        band=(lower, upper),
        demos=model.train_trajectories(p.task, z),
        dim_names=labels,
        units=[group_unit(label.split("/", 1)[0]) for label in labels],
        title=f"learned distribution of task {p.task} (mean or median, 2-sigma band, training demos)",
    )
    if robot is not None:
        files.update(robot_plots(result, robot, target, objects, retreat, context))
    if isinstance(out_dir, atomic.OutputSet):  # where the staged figures will be after the commit
        names = {key: name for name, key in FILE_KEYS.items()}
        return {key: out_dir.path(names[key]) for key in files}
    return files


def robot_plots(
    result: PlanResult,
    robot: Robot,
    target: Callable[[str], Path],
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
    context: CheckContext | None = None,
) -> dict[str, Path]:
    """The robot's figures of a planned hand-over, every time on the human's clock (t = 0 at the start
    of the human's motion, as in the report): ``motion.png``, the approach (and ``retreat``) against
    the limits the checks used; ``separation.png``, the approach's separation from the human the
    checks judged (``context.human``, else the assumed human); ``torques.png``, the joint torques of
    approach and retreat with the recognised task's object in ``objects`` while it is held, as the
    joint-torque checks compute them. ``target``: the path of a figure by file name."""
    from . import plots, plots_motion

    ctx = context if context is not None else CheckContext(objects=objects)
    tr = result.trajectory
    events = [(result.start_s, "robot starts"), (tr.end_s, "hand-over (robot at rest)")]
    later = [] if retreat is None else [retreat.trajectory]
    files = {"plot_motion": motion_plot(tr, later, robot, ctx.limits, target("motion.png"), events)}
    sep = separation_series(robot, tr, ctx.human, tr.dt_s or 0.01)
    files["plot_separation"] = plots_motion.plot_separation(
        sep.t_s,
        sep.body_m,
        sep.protective_m,
        sep.speed_ratio,
        target("separation.png"),
        hand_m=sep.hand_m,
        planning_limit_ratio=sep.planning_limit_ratio,
        judged=sep.judged,
        events=events,
        title=f"robot-human separation of the timed trajectory ({sep.human})",
    )
    track = plan_torques(result, robot, objects if objects is not None else ctx.objects, retreat,
                         every_sample=True)[0]  # fmt: skip
    if track is not None:
        held = ""
        if track.held.any():
            on = track.t_s[track.held]
            held = f"; shaded: holding {track.payload}, {on[0]:.2f}-{on[-1]:.2f} s"
        files["plot_torques"] = plots.plot_torques(
            track.t_s,
            track.ratio * track.limit_nm,
            track.limit_nm,
            target("torques.png"),
            effort_margin=1.0 - track.allowed_ratio,
            held=track.held,
            joint_names=list(track.joint_names),
            events=events,
            title="|joint torque|" + (", approach and retreat" if later else "")
            + " (t = 0: the human starts)" + held,
        )  # fmt: skip
    return files


def motion_plot(
    motion: Trajectory,
    later: Sequence[Trajectory],
    robot: Robot,
    limits: JointLimits | None,
    path: Path,
    events: Sequence[tuple[float, str]] = (),
    ticks_s: np.ndarray | None = None,
    title: str = "",
    labels: Sequence[str] = ("approach", "retreat"),
) -> Path:
    """``motion`` (then the ``later`` segments) against ``limits`` (the checks'; None: the robot's own,
    :meth:`JointLimits.from_robot`) and the URDF position limits, drawn into ``path``."""
    from . import plots_motion

    lim = limits if limits is not None else JointLimits.from_robot(robot)
    series = motion_series([motion, *later], lim, robot)
    return plots_motion.plot_joint_motion(
        series.t_s,
        (series.q, series.qd, series.qdd, series.jerk),
        (lim.lower_rad, lim.upper_rad, lim.velocity_rad_s, lim.acceleration_rad_s2, lim.jerk_rad_s3),
        path,
        position_bounds=series.position_bounds,
        segment=series.segment,
        joint_names=series.joint_names,
        events=events,
        ticks_s=ticks_s,
        segment_labels=labels,
        title=title
        or "the timed trajectory"
        + (" and its retreat" if later else "")
        + " against the limits the checks used (t = 0 at the start of the human's motion)",
    )
