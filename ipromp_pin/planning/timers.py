"""The planners' timers (:data:`~ipromp_pin.safety.retime.Timer`): a requested slow-down -> the
motion timed that much slower, for the one re-time-until-safe loop of :mod:`ipromp_pin.safety`.

- :func:`path_timer`: a joint path timed with toppra and ruckig (:func:`~ipromp_pin.motion.timing.time_path`)
  under the joint limits scaled by ``1/k``, ``1/k^2``, ``1/k^3`` and the checks' torque limits (the
  one-shot plan, the retreat); every timing follows the same geometric path;
- :func:`retarget_timer`: the closed loop's re-target from the commanded state onto the predicted
  motion followed at least ``k`` times slower (:meth:`~ipromp_pin.motion.retarget.Retargeter.plan`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..exceptions import InfeasibleError
from ..motion.retarget import ReferenceMotion, Retargeter
from ..motion.timing import time_path
from ..motion.trajectory import JointLimits, MotionState
from ..safety import Timed, Timer, TimingConstraints

LogFn = Callable[[str], None]
"""Where progress messages go (one line each)."""


def path_timer(
    path: np.ndarray,
    limits: JointLimits,
    constraints: TimingConstraints,
    rate_hz: float,
    start_s: float,
    say: LogFn,
    what: str = "timing",
) -> Timer:
    """A timer of the joint path ``path`` (M, n_joints) [rad] from rest to rest, its first sample at
    ``start_s`` [s] on the human's clock, at ``rate_hz`` [Hz].

    When toppra finds no profile under the torque limits (gravity alone exceeds them somewhere on the
    path: slowing down cannot help), the first timing is made without them and says so (``what``:
    the log line's tag); the joint-torque check then fails the motion.
    """
    torque = constraints.torque

    def timer(k: float) -> Timed:
        nonlocal torque
        scaled = limits if k == 1.0 else limits.scaled(1.0 / k, 1.0 / k**2, 1.0 / k**3)
        if torque is not None:
            try:
                motion, report = time_path(path, scaled, rate_hz=rate_hz, torque=torque, start_s=start_s)
                return Timed(motion, report, k, path)
            except InfeasibleError as exc:
                if k != 1.0:
                    raise
                say(f"[{what}] not timeable under the torque limits ({exc}): timed without them")
                torque = None
        motion, report = time_path(path, scaled, rate_hz=rate_hz, start_s=start_s)
        return Timed(motion, report, k, path)

    return timer


def retarget_timer(retargeter: Retargeter, state: MotionState, reference: ReferenceMotion) -> Timer:
    """A timer of the remaining motion from ``state`` (the commanded state at a control tick) onto
    ``reference``'s timeline; its scale is the followed reference's slow-down
    (:attr:`~ipromp_pin.motion.retarget.RetargetReport.time_scale`). The path is not the same for
    every slow-down (the blend to the reference changes with it). A motion is sampled when it is
    first used (:meth:`~ipromp_pin.motion.retarget.Planned.sample`)."""

    def timer(k: float) -> Timed:
        planned = retargeter.planned(state, reference, min_scale=k)
        return Timed(planned.sample, planned.report, planned.report.time_scale, None)

    return timer
