"""The run's figures: the conditioned prediction, the phase posterior, the learned distributions and
the joint torques of the timed trajectory (with the robot, when the trajectory has them).

:func:`write_plots` draws them with :mod:`ipromp_pin.outputs.plots` (imported when it draws:
matplotlib is only needed with ``--plots``) into a folder or an output set.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Demo
from ..handover.one_shot import PlanResult
from ..promp import IProMP
from ..robot import Robot
from ..signals.groups import group_unit
from .files import FILE_KEYS


def write_plots(
    result: PlanResult,
    model: IProMP,
    demo: Demo,
    out_dir: Path | atomic.OutputSet,
    robot: Robot | None = None,
) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions (and, with
    ``robot`` and the trajectory's ``effort_nm``, its joint torques), written into a folder or staged
    in an :class:`~ipromp_pin.atomic.OutputSet` (then they appear at its commit)."""
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
    tr = result.trajectory
    if robot is not None and tr.effort_nm is not None:
        model_limits = robot.model.effortLimit
        limit = [float(model_limits[robot.model.joints[int(j)].idx_v]) for j in robot.arm_joint_ids]
        t0 = result.start_s
        files["plot_torques"] = plots.plot_torques(
            tr.t_s,
            tr.effort_nm,
            np.array(limit),
            target("torques.png"),
            effort_margin=robot.settings.effort_margin,
            joint_names=list(robot.joint_names),
            title=f"|joint torque| of the timed trajectory (t = 0 at the robot's start, {t0:.2f} s); "
            "the object included while held",
        )
    if isinstance(out_dir, atomic.OutputSet):  # where the staged figures will be after the commit
        names = {key: name for name, key in FILE_KEYS.items()}
        return {key: out_dir.path(names[key]) for key in files}
    return files
