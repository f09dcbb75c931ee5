"""The run's figures: the conditioned prediction, the phase posterior, the learned distributions and
the joint torques of the timed trajectory (with the robot).

:func:`write_plots` draws them with :mod:`ipromp_pin.outputs.plots` (imported when it draws:
matplotlib is only needed with ``--plots``) into a folder or an output set.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Demo
from ..planning.one_shot import PlanResult
from ..promp import IProMP
from ..robot import Robot
from ..robot.objects import ObjectTable
from ..signals.groups import group_unit
from .files import FILE_KEYS
from .torque_preview import plan_torques


def write_plots(
    result: PlanResult,
    model: IProMP,
    demo: Demo,
    out_dir: Path | atomic.OutputSet,
    robot: Robot | None = None,
    objects: ObjectTable | None = None,
) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions (and, with
    ``robot``, the timed trajectory's joint torques, the recognised task's object in ``objects``
    included while held, as the joint-torque check computes them), written into a folder or staged
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
    track = None if robot is None else plan_torques(result, robot, objects, every_sample=True)[0]
    if track is not None:
        files["plot_torques"] = plots.plot_torques(
            result.trajectory.t_s - result.start_s,
            track.ratio * track.limit_nm,
            track.limit_nm,
            target("torques.png"),
            effort_margin=1.0 - track.allowed_ratio,
            held=track.held,
            joint_names=list(track.joint_names),
            title=f"|joint torque| of the timed trajectory (t = 0 at the robot's start, {result.start_s:.2f} "
            "s on the human's clock)" + (f"; shaded: holding {track.payload}" if track.held.any() else ""),
        )
    if isinstance(out_dir, atomic.OutputSet):  # where the staged figures will be after the commit
        names = {key: name for name, key in FILE_KEYS.items()}
        return {key: out_dir.path(names[key]) for key in files}
    return files
