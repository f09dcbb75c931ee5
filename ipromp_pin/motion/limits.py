"""Joint limit profiles of the closed loop: the robot settings' conservative profile, and one derived
from the training demonstrations.

* ``conservative``: the URDF's velocity limits and the settings file's acceleration and jerk limits
  (:meth:`~ipromp_pin.motion.trajectory.JointLimits.from_robot`; for Baxter 1.0 rad/s^2 and 10 rad/s^3
  on every joint, sources in ``robots/baxter_left.toml``).
* ``demonstrated``: per joint, a high percentile of the training demonstrations' own peak |velocity|,
  |acceleration| and |jerk| (Savitzky-Golay derivatives of the recorded joint angles over a window of
  :attr:`~ipromp_pin.robot.DemoLimitRecipe.window_s`), never above the URDF's velocity limits and
  never below the conservative acceleration and jerk limits. It is derived from the demonstrations
  the model is trained on (never from a test demo), and at most :data:`PROFILE_CEILING_FACTOR` times
  the conservative accelerations and jerks, so it differs between training sets; the
  settings file's
  ``[limits.demonstrated]`` table holds the recipe (percentile and window,
  :class:`~ipromp_pin.robot.DemoLimitRecipe`).
* a profile file (TOML, :func:`read_limit_profile`): explicit limits, e.g. a demonstrated profile
  written by ``ipromp-pin replay`` (``limits.toml``) and reused.

Every profile's position limits are the URDF's shrunk by the settings' margin.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data import ROBOT, Demo
from ..exceptions import PipelineError
from ..fields import Table, field_errors
from ..inputs import load_toml
from ..robot import DemoLimitRecipe, Robot
from ..robot.ranges import PLAUSIBLE_RANGES
from .trajectory import JointLimits

PROFILE_NAMES = ("conservative", "demonstrated")
"""Built-in limit profiles (anything else is read as a profile file)."""

PROFILE_CEILING_FACTOR = 20.0
"""A profile's accelerations and jerks are at most this multiple of the settings' (conservative)
ones: Baxter 20 rad/s^2 and 200 rad/s^3. Basis: the demonstrated profiles of the real recordings
reach 5.4 rad/s^2 and 81 rad/s^3 (``chen2017_handover``, 90th percentile of 99 demos; 4.4 and 59 for
``handover_20171128``), so the ceiling leaves them a factor 2.5 or more; a profile above it would
command what the arm was never shown to do (and the report would call it within limits)."""


@dataclass(frozen=True)
class LimitProfile:
    """A named set of joint limits with where its numbers come from.

    Attributes:
        name: ``"conservative"``, ``"demonstrated"`` or the name in a profile file.
        limits: The limits (positions with the settings' margin).
        source: One line saying where the numbers come from.
    """

    name: str
    limits: JointLimits
    source: str

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        lim = self.limits
        return {
            "name": self.name,
            "source": self.source,
            "joint_names": list(lim.joint_names),
            "velocity_rad_s": [float(v) for v in lim.velocity_rad_s],
            "acceleration_rad_s2": [float(v) for v in lim.acceleration_rad_s2],
            "jerk_rad_s3": [float(v) for v in lim.jerk_rad_s3],
        }

    def to_toml(self) -> str:
        """The profile as a profile file (readable by :func:`read_limit_profile`)."""
        d = self.to_dict()

        def arr(v: list[float]) -> str:
            return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"

        return (
            "# Joint limit profile for ipromp-pin replay / evaluate --limits\n"
            f"# joints: {', '.join(d['joint_names'])}\n"
            f'name = "{self.name}"\nsource = "{self.source}"\n'
            f"velocity_rad_s = {arr(d['velocity_rad_s'])}\n"
            f"acceleration_rad_s2 = {arr(d['acceleration_rad_s2'])}\n"
            f"jerk_rad_s3 = {arr(d['jerk_rad_s3'])}\n"
        )


def conservative_profile(robot: Robot) -> LimitProfile:
    """The settings' profile: URDF velocities, the settings file's accelerations and jerks."""
    return LimitProfile(
        "conservative",
        JointLimits.from_robot(robot),
        f"velocities from the URDF, accelerations and jerks from {robot.settings.path.name} [limits]",
    )


def demo_peaks(demos: Iterable[Demo], window_s: float, group: str = ROBOT) -> np.ndarray:
    """Per demo, the peak |velocity|, |acceleration| and |jerk| of every joint, (n_demos, 3, J),
    in [rad/s], [rad/s^2], [rad/s^3] (Savitzky-Golay derivatives, order 4, window ``window_s``)."""
    from scipy.signal import savgol_filter  # here: importing scipy.signal takes about a second

    out = []
    for d in demos:
        q = d.groups[group]
        dt = float(np.median(np.diff(d.t)))
        win = int(round(window_s / dt)) // 2 * 2 + 1
        win = min(max(win, 7), (q.shape[0] - 1) // 2 * 2 + 1)
        if win < 5:
            continue
        order = min(4, win - 2)
        peaks = [
            np.max(np.abs(savgol_filter(q, win, order, deriv=k, delta=dt, axis=0, mode="interp")), axis=0)
            for k in (1, 2, 3)
        ]
        out.append(np.stack(peaks))
    return np.array(out)


def demonstrated_profile(
    robot: Robot, demos: Iterable[Demo], recipe: DemoLimitRecipe | None = None, label: str = ""
) -> LimitProfile:
    """The profile derived from (training) demonstrations; see the module docstring.

    Args:
        robot: The robot (URDF velocity limits, conservative profile, position limits).
        demos: The training demonstrations (their robot group, joints in the settings' order).
        recipe: Percentile and window (default :class:`DemoLimitRecipe`).
        label: What the demos are, for the profile's ``source`` line (e.g. the dataset).
    """
    recipe = recipe or robot.settings.demonstrated_limits
    demos = list(demos)
    peaks = demo_peaks(demos, recipe.window_s)
    if peaks.shape[0] == 0:
        raise PipelineError("demonstrated limit profile: no demonstration long enough to differentiate")
    p = np.percentile(peaks, recipe.percentile, axis=0)  # (3, J)
    base = JointLimits.from_robot(robot)
    limits = JointLimits(
        lower_rad=base.lower_rad,
        upper_rad=base.upper_rad,
        velocity_rad_s=np.minimum(p[0], robot.velocity_rad_s),
        acceleration_rad_s2=np.clip(
            p[1], base.acceleration_rad_s2, base.acceleration_rad_s2 * PROFILE_CEILING_FACTOR
        ),
        jerk_rad_s3=np.clip(p[2], base.jerk_rad_s3, base.jerk_rad_s3 * PROFILE_CEILING_FACTOR),
        joint_names=base.joint_names,
    )
    what = f"{peaks.shape[0]} training demos" + (f" of {label}" if label else "")
    source = (
        f"{recipe.percentile:g}th percentile of the per-demo peaks over {what} (Savitzky-Golay, "
        f"{recipe.window_s:g} s window); velocity capped at the URDF's, acceleration and jerk at least "
        "the conservative profile's"
    )
    return LimitProfile("demonstrated", limits, source)


PROFILE_KEYS = ("name", "source", "velocity_rad_s", "acceleration_rad_s2", "jerk_rad_s3")
"""The keys of a profile file (anything else is refused, naming the known key it resembles)."""


def _vector(doc: Table, key: str, n: int) -> np.ndarray:
    """A profile's limits (n,): a number or one per joint, positive, in the settings' plausible range."""
    arr = doc.vector(key, n, scalar=True)
    bad = arr <= 0
    if np.any(bad):
        raise doc.error(key, f"value {arr[bad][0]} is not positive and finite (values: {arr.tolist()})")
    rng = PLAUSIBLE_RANGES[f"limits.{key}"]
    rng.check(arr, key, doc.error_fn)
    return arr


def check_ceiling(values: np.ndarray, settings: np.ndarray, robot: Robot, path: Path, key: str) -> None:
    """Refuse a profile's ``values`` (J,) above :data:`PROFILE_CEILING_FACTOR` times the settings'."""
    over = values > settings * PROFILE_CEILING_FACTOR * (1 + 1e-9)
    if np.any(over):
        j = int(np.argmax(over))
        raise PipelineError(
            f"{path}: field '{key}': {values[j]:g} for {robot.joint_names[j]} is above what the robot "
            f"settings allow ({PROFILE_CEILING_FACTOR:g} x {settings[j]:g} from {robot.settings.path.name} "
            "[limits])"
        )


def read_limit_profile(path: str | Path, robot: Robot) -> LimitProfile:
    """Read a profile file: ``velocity_rad_s``, ``acceleration_rad_s2``, ``jerk_rad_s3`` (a number or
    one per arm joint, positive and finite, within the settings' plausible ranges
    (:data:`~ipromp_pin.robot.ranges.PLAUSIBLE_RANGES`); velocities at most the URDF's, accelerations
    and jerks at most :data:`PROFILE_CEILING_FACTOR` times the settings'), optional ``name`` and
    ``source``.

    Raises:
        PipelineError: missing or unreadable file, bad TOML, a missing, non-positive or non-finite
            value, a velocity above the URDF's (the message names the file and the field).
    """
    path = Path(path)
    try:
        raw = load_toml(path, "limit profile", lambda problem: PipelineError(f"{path}: {problem}"))
    except FileNotFoundError:
        raise PipelineError(
            f"{path}: limit profile not found (use {' or '.join(PROFILE_NAMES)}, or a profile file)"
        ) from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise PipelineError(f"{path}: not a valid TOML limit profile: {exc}") from None
    doc = Table(raw, "", field_errors(PipelineError, path), PROFILE_KEYS)
    n = robot.n_joints
    vel = _vector(doc, "velocity_rad_s", n)
    over = vel > robot.velocity_rad_s * (1 + 1e-9)
    if np.any(over):
        j = int(np.argmax(over))
        raise PipelineError(
            f"{path}: field 'velocity_rad_s': {vel[j]} rad/s for {robot.joint_names[j]} is above the "
            f"URDF's limit {robot.velocity_rad_s[j]}"
        )
    acc = _vector(doc, "acceleration_rad_s2", n)
    jerk = _vector(doc, "jerk_rad_s3", n)
    base = JointLimits.from_robot(robot)
    check_ceiling(acc, base.acceleration_rad_s2, robot, path, "acceleration_rad_s2")
    check_ceiling(jerk, base.jerk_rad_s3, robot, path, "jerk_rad_s3")
    name = doc.text("name", path.stem)
    source = doc.text("source", f"profile file {path.name}")
    limits = JointLimits(base.lower_rad, base.upper_rad, vel, acc, jerk, base.joint_names)
    return LimitProfile(name, limits, source)


def check_profile_choice(choice: str, robot: Robot, source: str) -> LimitProfile | None:
    """Validate a profile choice before any computation: a built-in name (None) or a profile file
    (read and returned).

    Raises:
        PipelineError: an unknown name that is not a file either (naming ``source`` and ``limits``).
    """
    if choice in PROFILE_NAMES:
        return None
    if not Path(choice).suffix and not Path(choice).exists():
        raise PipelineError(
            f"{source}: field 'limits': unknown limit profile '{choice}' "
            f"(use {' or '.join(PROFILE_NAMES)}, or a profile file)"
        )
    return read_limit_profile(choice, robot)


def choose_limit_profile(
    choice: str | LimitProfile,
    robot: Robot,
    train: Iterable[Demo],
    label: str,
    recipe: DemoLimitRecipe | None = None,
) -> LimitProfile:
    """The limit profile a closed loop runs with (``replay`` and ``evaluate --closed-loop`` alike):
    ``"conservative"`` (the robot settings'), ``"demonstrated"`` (derived from ``train``, the model's
    training demos, with ``recipe`` or the settings' recipe; ``label`` names them), a profile already
    read, or a profile file's path."""
    if isinstance(choice, LimitProfile):
        return choice
    if choice == "conservative":
        return conservative_profile(robot)
    if choice == "demonstrated":
        return demonstrated_profile(robot, train, recipe or robot.settings.demonstrated_limits, label)
    return read_limit_profile(choice, robot)
