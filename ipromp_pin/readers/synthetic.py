"""Synthetic hand-over demonstrations with known ground truth.

:func:`make_synthetic_dataset` mimics the shared recordings: a human hands an
object to Baxter's left arm while wearing a Myo armband. The human's channels (Myo
orientation, EMG) are modelled on ``chen2017_handover``; the robot's side (its start and
hand-over configurations) and the human's hand path on ``handover_20171128``, the session
whose tracked partner stands where the robot settings' assumed human stands
(``robots/baxter_left.toml`` ``[human.assumed]``, :data:`HUMAN_TORSO_M`), so that the
hand-over lies where that session put it relative to the human's torso
(``benchmarks/handover_geometry.py``).

* The human forearm orientation follows nearly the same path in every task
  (one common start and end orientation, a task-specific tilt of only
  :data:`TASK_ORIENTATION_TILT_DEG`), so motion alone barely separates tasks.
* The EMG envelope has a task-specific channel pattern (what separates tasks),
  derived from the median real envelopes (:data:`EMG_REST`, :data:`EMG_ACTIVE`).
* Each demo lasts ``duration_s = alpha * NOMINAL_DURATION_S`` with
  ``alpha`` drawn so that durations are uniform in :data:`DURATION_RANGE_S`;
  every signal is a function of the phase ``t / duration_s``, so the true
  phase ratio of a demo is ``demo.duration_s / NOMINAL_DURATION_S``
  (:func:`true_alpha`).
* Every demo has a latent hand-over offset ``d`` (3,) in [m] in the base frame,
  drawn with the across-demo spread of the real hand-over points
  (:data:`HANDOVER_OFFSET_STD_M`, normal truncated at 2.5 std, shortened if the
  arm could not follow it inside its joint limits): where this demo's hand-over
  happens relative to the task's nominal point. Both partners depend on it:

  - the human's hand ends at the offset point, and the forearm turns towards it
    early in the motion: the Myo orientation is rotated (in the world frame) by
    ``s_aim(phase) * AIM_GAIN_RAD_PER_M @ d`` where ``s_aim`` rises from 0 to 1
    within the first :data:`AIM_PHASE` of the motion, so the observed start of
    the motion reveals ``d``;
  - the robot's hand-over configuration is the task's configuration plus
    ``coupling * H @ d`` (:func:`offset_maps`: the gripper moves by ``d`` to
    first order and re-orients as the real robot did), plus an independent
    residual in the null space of the gripper's position Jacobian (scaled
    :data:`HANDOVER_Q_RESIDUAL_STD_RAD`, the part of the real configurations
    the hand-over point does not explain).

  The ground truth ``d`` is ``demo.extras["handover_offset"]`` (T, 3), constant.
* The robot group holds Baxter left-arm joint angles moving from the measured
  start configuration to that hand-over configuration along a minimum-jerk
  profile, inside Baxter's joint limits.
* ``extras["hand_position"]`` is a human hand path in the Baxter base frame
  [m], from in front of the torso to beside the robot's hand-over point (shifted by ``d``).

Everything is deterministic for a given ``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from scipy.spatial.transform import Rotation

from ..data import ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..signals.groups import ACC, EMG, ORIENTATION
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ, emg_envelope, quaternion_continuity
from .streams import full_duration_s

NOMINAL_DURATION_S = 3.8
"""Nominal demo duration in [s]; a demo's true phase ratio is ``duration_s / NOMINAL_DURATION_S``."""
nominal_duration_s = NOMINAL_DURATION_S
"""Alias of :data:`NOMINAL_DURATION_S`."""

DURATION_RANGE_S = (3.0, 4.6)
"""Demo durations are drawn uniformly in this range, in [s] (as in the real recordings)."""

JOINT_NAMES = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
"""Baxter left-arm joints, URDF kinematic order."""

BAXTER_LEFT_LIMITS_RAD = np.array(
    [
        [-1.7016, 1.7016],
        [-2.147, 1.047],
        [-3.0541, 3.0541],
        [-0.05, 2.618],
        [-3.059, 3.059],
        [-1.5707, 2.094],
        [-3.059, 3.059],
    ]
)
"""Baxter left-arm joint position limits [rad] (baxter_description URDF), rows in JOINT_NAMES order."""

LIMIT_MARGIN_RAD = 0.1
"""Synthetic configurations stay this far inside the joint limits, in [rad]."""

# The robot's side is measured on the real handover_20171128 recordings (all 90 demos, read with
# ipromp_pin.robot.recordings.read_recordings at 50 Hz; benchmarks/handover_geometry.py prints every
# value below): median of the first sample of the robot group (the start is the same for all three
# tasks, std < 0.07 rad).
START_Q_RAD = np.array([0.074, -0.889, -0.947, 1.446, 0.533, 1.299, -0.119])
"""Start configuration [rad] (median first sample of the real demos)."""

# Median of the last sample of the robot group per task (the hand-over pose), and the
# across-demo standard deviation of that last sample, same recordings.
TASKS = ("rod", "wrench", "tape")
"""Names of the first three synthetic tasks: the human's channels modelled on chen2017's aluminum_hold,
spanner_handover, tape_hold, the robot's hand-over on handover_20171128's pincer, screwdriver, tape."""
HANDOVER_Q_RAD = np.array(
    [
        [-0.518, -0.777, -0.747, 0.507, 0.528, 1.393, -0.318],  # pincer
        [-0.543, -0.681, -0.749, 0.513, 0.562, 1.540, -0.182],  # screwdriver
        [-0.555, -0.768, -0.757, 0.504, 0.535, 1.531, -0.134],  # tape
    ]
)
"""Task hand-over configurations [rad] (median last sample of the real demos per task)."""
HANDOVER_Q_STD_RAD = np.array([0.064, 0.097, 0.047, 0.194, 0.067, 0.118, 0.083])
"""Across-demo std of the hand-over configuration [rad] (mean of the three tasks' std)."""
# Same recordings: per task, least-squares regression of the last robot sample on the last
# endpoint_state position (both centred); mean over the three tasks of the per-axis std of the
# end-point and of the per-joint std of the regression residual.
HANDOVER_OFFSET_STD_M = np.array([0.026, 0.035, 0.042])
"""Across-demo std of the hand-over point per base-frame axis (x, y, z) in [m]."""
HANDOVER_Q_RESIDUAL_STD_RAD = np.array([0.053, 0.069, 0.039, 0.157, 0.061, 0.089, 0.066])
"""Std of the hand-over configuration not explained by the hand-over point [rad] (per joint)."""
HANDOVER_POINT_M = np.array([[0.974, 0.227, 0.418], [0.921, 0.268, 0.282], [0.943, 0.239, 0.397]])
"""Robot end-point position at hand-over [m] in the base frame (median last endpoint_state per task)."""

# Position Jacobian (base-frame axes) of the "ee" frame at HANDOVER_Q_RAD, computed once from
# robots/baxter_left.toml's forward kinematics (ipromp_pin.robot.kinematics.ee_positions, central
# differences); left_w2 does not move the gripper's position.
HANDOVER_JACOBIAN_M_PER_RAD = np.array(
    [
        [
            [0.008, 0.012, 0.021, -0.201, 0.039, -0.330, 0.0],
            [0.914, 0.003, 0.585, -0.212, 0.389, 0.030, 0.0],
            [0.0, -0.811, -0.178, -0.474, -0.006, -0.201, 0.0],
        ],
        [
            [0.014, -0.086, 0.003, -0.259, 0.046, -0.367, 0.0],
            [0.859, -0.021, 0.565, -0.184, 0.394, 0.041, 0.0],
            [0.0, -0.761, -0.171, -0.401, -0.007, -0.116, 0.0],
        ],
        [
            [0.038, -0.014, 0.035, -0.227, 0.056, -0.353, 0.0],
            [0.867, -0.003, 0.566, -0.178, 0.393, 0.047, 0.0],
            [0.0, -0.766, -0.169, -0.431, -0.008, -0.152, 0.0],
        ],
    ]
)
"""Per task (3, 3, 7): gripper position change [m] per joint change [rad] at the hand-over configuration."""
# Same real recordings as above: per task, least-squares regression of the last robot sample on
# the last endpoint_state position (both centred). Only its null-space part is used (offset_maps).
HANDOVER_REGRESSION_RAD_PER_M = np.array(
    [
        [
            [0.199, 0.534, 0.096],
            [0.222, 1.022, -1.035],
            [0.713, -0.617, -0.002],
            [1.176, -2.305, -0.354],
            [-0.532, 0.821, -0.498],
            [-3.794, 1.695, 0.181],
            [-3.003, 2.734, -0.644],
        ],
        [
            [-0.530, 0.815, 0.010],
            [2.588, -0.439, -1.263],
            [-0.765, 0.270, 0.258],
            [-4.570, 0.702, -0.259],
            [0.366, 0.656, -0.564],
            [-0.104, -0.462, 0.482],
            [-0.182, 0.936, -0.242],
        ],
        [
            [-0.503, 1.949, -0.032],
            [1.912, -1.655, -0.467],
            [-0.340, 0.188, -0.603],
            [-2.714, 3.626, -1.703],
            [0.475, -0.171, -0.058],
            [-1.418, -2.070, 0.892],
            [0.065, 0.079, 0.088],
        ],
    ]
)
"""Per task (3, 7, 3): real hand-over configuration change [rad] per hand-over point change [m]."""

FOREARM_LENGTH_M = 0.30
"""Human forearm length [m]: a lateral/vertical hand offset d turns the forearm by ~d / length [rad]."""
AIM_GAIN_RAD_PER_M = np.array(
    [
        [1.5, 0.0, 0.0],
        [-1.0, 0.0, 1.0 / FOREARM_LENGTH_M],
        [0.0, -1.0 / FOREARM_LENGTH_M, 0.0],
    ]
)
"""Forearm rotation vector [rad] per hand-over offset [m] (3, 3), world axes taken as the base frame's.

The forearm points towards the robot (-x): a sideways (y) offset yaws it about z, a vertical (z)
offset pitches it about y; reaching further (x) extends the elbow (pitch) and supinates the
forearm (roll about x), so all three offset axes show in the orientation.
"""
AIM_PHASE = 0.25
"""The forearm has turned towards the hand-over point by this phase of the motion (min-jerk from 0)."""
ORIENTATION_JITTER_DEG = 3.0
"""Per-axis std of the demo's start and end forearm orientation not explained by the offset, in [deg]."""
EMG_GAIN_LOG_STD = 0.15
"""Std of the per-demo, per-channel EMG gain (log scale)."""
EMG_RAW_NOISE = 0.25
"""Relative noise of the raw EMG samples before the envelope."""
RESIDUAL_SCALE = 0.5
"""The hand-over configuration's independent residual is this times :data:`HANDOVER_Q_RESIDUAL_STD_RAD`."""
"""The forearm has turned towards the hand-over point by this phase of the motion."""

# Median Myo orientation (w, x, y, z) of the first and last sample over all tasks.
ORIENTATION_START_WXYZ = np.array([0.255, 0.284, 0.566, 0.726])
ORIENTATION_END_WXYZ = np.array([0.550, 0.080, 0.300, 0.755])
TASK_ORIENTATION_TILT_DEG = 2.0
"""Task-specific tilt of the end orientation, in [deg] (small: motion barely separates tasks)."""

# Median EMG envelope per task (Myo processed-EMG units) at the start of the demo and around
# mid-motion (phase 0.5), same recordings.
EMG_REST = np.array(
    [
        [73, 228, 125, 51, 39, 41, 68, 107],  # aluminum_hold
        [78, 64, 42, 31, 27, 49, 48, 61],  # spanner_handover
        [347, 141, 63, 87, 102, 34, 47, 139],  # tape_hold
    ],
    dtype=float,
)
EMG_ACTIVE = np.array(
    [
        [195, 383, 167, 80, 86, 118, 284, 418],
        [592, 156, 91, 67, 72, 220, 166, 359],
        [606, 269, 120, 90, 167, 63, 72, 319],
    ],
    dtype=float,
)

HUMAN_TORSO_M = np.array([1.27, -0.26, 0.15])
"""Where the synthetic demos' human stands: its torso in the Baxter base frame [m], facing the robot
(the median tracked torso of handover_20171128, the assumed human of ``robots/baxter_left.toml``)."""
# handover_20171128 (benchmarks/handover_geometry.py): the tracked hand at the demo's start relative
# to the torso, and at its end relative to the recorded gripper (medians over the 90 demos).
HAND_START_M = HUMAN_TORSO_M + np.array([-0.238, 0.009, 0.132])
"""Human hand start position [m] in the Baxter base frame (in front of the torso, object held up)."""
HAND_FROM_GRIPPER_M = np.array([-0.048, -0.075, 0.038])
"""The hand ends this far from the robot's hand-over point, in [m] (base frame; the object between)."""


def true_alpha(demo: Demo) -> float:
    """Ground-truth phase ratio of a synthetic demo: ``duration_s / NOMINAL_DURATION_S``."""
    return full_duration_s(demo) / NOMINAL_DURATION_S


def min_jerk(x: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 10x^3 - 15x^4 + 6x^5 on x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def handover_offset(demo: Demo) -> np.ndarray:
    """Ground-truth latent hand-over offset (3,) of a synthetic demo in [m], base frame.

    The task's nominal hand-over point plus this offset is where the human's hand goes;
    the robot's gripper goes to the nominal point plus ``coupling`` times it.
    """
    offset = demo.extras.get("handover_offset")
    if offset is None:
        raise DataError(demo.source, "extras.handover_offset", "missing (not a synthetic demo)")
    return np.asarray(offset, dtype=float)[0].copy()


def offset_maps(jacobian: np.ndarray, regression: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint-space response of the robot to a hand-over point offset.

    Args:
        jacobian: (3, 7) gripper position Jacobian [m/rad] at the hand-over configuration.
        regression: (7, 3) measured configuration change per hand-over point change [rad/m].

    Returns:
        ``H`` (7, 3) = ``J^+ + N B`` in [rad/m], with ``J H = I`` (the gripper follows the offset to
        first order; the null-space part is the measured re-orientation of the gripper), and the
        null-space projector ``N = I - J^+ J`` (7, 7).
    """
    j_pinv = np.linalg.pinv(jacobian)
    null_space = np.eye(jacobian.shape[1]) - j_pinv @ jacobian
    return j_pinv + null_space @ regression, null_space


def _feasible_fraction(q: np.ndarray, dq: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Largest s in [0, 1] with lo <= q + s dq <= hi (q (7,) inside the limits), all in [rad]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(dq > 0, (hi - q) / dq, np.where(dq < 0, (lo - q) / dq, np.inf))
    return float(np.clip(np.min(room), 0.0, 1.0))


class _TaskDefinitions(TypedDict):
    """Per-task parameters of a synthetic dataset, one row per task (see :func:`_task_definitions`)."""

    names: list[str]
    offset_to_q: np.ndarray
    null_space: np.ndarray
    q_end: np.ndarray
    point: np.ndarray
    rest: np.ndarray
    active: np.ndarray


def _task_definitions(n_tasks: int) -> _TaskDefinitions:
    """Task parameters; tasks beyond the measured three are fixed blends of them."""
    names = list(TASKS[:n_tasks])
    q_end = list(HANDOVER_Q_RAD[:n_tasks])
    jac = list(HANDOVER_JACOBIAN_M_PER_RAD[:n_tasks])
    regression = list(HANDOVER_REGRESSION_RAD_PER_M[:n_tasks])
    point = list(HANDOVER_POINT_M[:n_tasks])
    rest = list(EMG_REST[:n_tasks])
    active = list(EMG_ACTIVE[:n_tasks])
    extra_rng = np.random.default_rng(12345)  # fixed: task definitions do not depend on the seed
    for k in range(3, n_tasks):
        w = extra_rng.dirichlet(np.ones(3))
        names.append(f"task{k}")
        q_end.append(w @ HANDOVER_Q_RAD + extra_rng.normal(0.0, 0.05, 7))
        jac.append(np.tensordot(w, HANDOVER_JACOBIAN_M_PER_RAD, axes=1))
        regression.append(np.tensordot(w, HANDOVER_REGRESSION_RAD_PER_M, axes=1))
        point.append(w @ HANDOVER_POINT_M)
        perm = extra_rng.permutation(8)
        rest.append((w @ EMG_REST)[perm])
        active.append((w @ EMG_ACTIVE)[extra_rng.permutation(8)] * extra_rng.uniform(0.8, 1.3))
    offset_to_q, null_space = zip(
        *(offset_maps(j, b) for j, b in zip(jac, regression, strict=True)), strict=True
    )
    lo, hi = BAXTER_LEFT_LIMITS_RAD[:, 0] + LIMIT_MARGIN_RAD, BAXTER_LEFT_LIMITS_RAD[:, 1] - LIMIT_MARGIN_RAD
    return {
        "names": names,
        "offset_to_q": np.array(offset_to_q),
        "null_space": np.array(null_space),
        "q_end": np.clip(np.array(q_end), lo, hi),
        "point": np.array(point),
        "rest": np.array(rest),
        "active": np.array(active),
    }


def make_synthetic_dataset(
    n_tasks: int = 3,
    n_demos: int = 20,
    seed: int | None = 0,
    rate_hz: float = 50.0,
    *,
    noise: float = 1.0,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    coupling: float = 1.0,
) -> Dataset:
    """Synthetic hand-over demos with known ground truth.

    Args:
        n_tasks: Number of tasks (>= 1); the first three are modelled on the
            real tasks, further ones are fixed blends of them.
        n_demos: Demos per task (>= 2).
        seed: Random seed (same seed, same dataset).
        rate_hz: Sampling rate in [Hz].
        noise: Scale of the observation noise and of the demo-to-demo variation
            (1 = realistic, 0 = every demo of a task follows its nominal path).
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
        coupling: How much the robot's hand-over configuration follows the demo's
            latent hand-over offset (1 = its gripper goes where the human's hand
            goes, 0 = the robot ignores it: nothing to learn from the human's motion
            about the robot beyond the task and timing).

    Returns:
        Dataset with groups ``"orientation"`` (4), ``"emg"`` (8), ``"acc"`` (3)
        and ``"robot"`` (7 Baxter left-arm joints), plus ``extras["hand_position"]``
        (T, 3) in [m] and ``extras["handover_offset"]`` (T, 3), the demo's constant
        latent hand-over offset in [m] (see :func:`handover_offset`).
        ``root`` is ``"synthetic(seed=...)"``.
    """
    if int(n_tasks) < 1:
        raise DataError("synthetic", "n_tasks", f"must be >= 1, got {n_tasks}")
    if int(n_demos) < 2:
        raise DataError("synthetic", "n_demos", f"must be >= 2, got {n_demos}")
    if not (np.isfinite(rate_hz) and rate_hz >= 10.0):
        raise DataError("synthetic", "rate_hz", f"must be >= 10 Hz, got {rate_hz}")
    if not (np.isfinite(noise) and noise >= 0):
        raise DataError("synthetic", "noise", f"must be >= 0, got {noise}")
    if not (np.isfinite(coupling) and 0.0 <= coupling <= 1.5):
        raise DataError("synthetic", "coupling", f"must be in [0, 1.5], got {coupling}")
    rng = np.random.default_rng(seed)
    setting = _Setting(_task_definitions(int(n_tasks)), rate_hz, noise, emg_cutoff_hz, coupling, seed)
    demos: dict[str, list[Demo]] = {}
    for k, task in enumerate(setting.defs["names"]):
        # Task-specific small tilt of the end orientation about a fixed axis per task.
        axis = np.array([np.cos(2.1 * k), np.sin(2.1 * k), 0.3])
        tilt = Rotation.from_rotvec(np.deg2rad(TASK_ORIENTATION_TILT_DEG) * k * axis / np.linalg.norm(axis))
        demos[task] = [_synthetic_demo(rng, setting, k, task, i, tilt) for i in range(int(n_demos))]
    return Dataset(root=f"synthetic(seed={seed})", demos=demos)


@dataclass(frozen=True)
class _Setting:
    """What every demo of one synthetic dataset shares (see :func:`make_synthetic_dataset`)."""

    defs: _TaskDefinitions
    rate_hz: float
    noise: float
    emg_cutoff_hz: float
    coupling: float
    seed: int | None
    r_start: Rotation = field(default_factory=lambda: Rotation.from_quat(np.roll(ORIENTATION_START_WXYZ, -1)))
    r_end: Rotation = field(default_factory=lambda: Rotation.from_quat(np.roll(ORIENTATION_END_WXYZ, -1)))
    lo: np.ndarray = field(default_factory=lambda: BAXTER_LEFT_LIMITS_RAD[:, 0] + LIMIT_MARGIN_RAD)
    hi: np.ndarray = field(default_factory=lambda: BAXTER_LEFT_LIMITS_RAD[:, 1] - LIMIT_MARGIN_RAD)


def _demo_offset(rng: np.random.Generator, s: _Setting, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A demo's latent hand-over offset (3,) in [m] (base frame) and the robot's hand-over
    configuration (7,) in [rad].

    The configuration is the task's, changed by its response to the offset plus a residual that
    leaves the gripper's position unchanged (to first order), as on the real robot. An offset the arm
    cannot follow inside its joint limits is shortened (the human hands over where the robot can
    reach).
    """
    offset = np.clip(rng.normal(0.0, 1.0, 3), -2.5, 2.5) * HANDOVER_OFFSET_STD_M * s.noise
    residual = rng.normal(0, RESIDUAL_SCALE * s.noise, 7) * HANDOVER_Q_RESIDUAL_STD_RAD
    q_base = np.clip(s.defs["q_end"][k] + s.defs["null_space"][k] @ residual, s.lo, s.hi)
    dq = s.coupling * s.defs["offset_to_q"][k] @ offset
    offset = offset * _feasible_fraction(q_base, dq, s.lo, s.hi)
    q1 = np.clip(q_base + s.coupling * s.defs["offset_to_q"][k] @ offset, s.lo, s.hi)
    return offset, q1


def _synthetic_demo(rng: np.random.Generator, s: _Setting, k: int, task: str, i: int, tilt: Rotation) -> Demo:
    """Demo ``i`` of task ``k`` (the draws from ``rng`` in a fixed order: same seed, same demos)."""
    noise, dt = s.noise, 1.0 / s.rate_hz
    duration = rng.uniform(*DURATION_RANGE_S)
    n = int(round(duration * s.rate_hz)) + 1
    t = dt * np.arange(n)
    phase = t / t[-1]
    offset, q1 = _demo_offset(rng, s, k)

    # Human forearm orientation: shared path, turned early towards the hand-over point,
    # demo-to-demo variation, sensor noise.
    jitter0 = Rotation.from_rotvec(rng.normal(0, np.deg2rad(ORIENTATION_JITTER_DEG) * noise, 3))
    jitter1 = Rotation.from_rotvec(rng.normal(0, np.deg2rad(ORIENTATION_JITTER_DEG) * noise, 3))
    ra, rb = jitter0 * s.r_start, jitter1 * tilt * s.r_end
    rel = (ra.inv() * rb).as_rotvec()
    s_h = min_jerk((phase - rng.uniform(0.0, 0.05)) / rng.uniform(0.7, 0.8))
    r = ra * Rotation.from_rotvec(s_h[:, None] * rel[None, :])
    s_aim = min_jerk(phase / AIM_PHASE)
    r = Rotation.from_rotvec(s_aim[:, None] * (AIM_GAIN_RAD_PER_M @ offset)[None, :]) * r
    r = Rotation.from_rotvec(rng.normal(0, 0.004 * noise, (n, 3))) * r
    quat = quaternion_continuity(np.roll(r.as_quat(), 1, axis=1))
    if quat[0, 0] < 0:
        quat = -quat
    # Accelerometer: gravity in the sensor frame [g] plus the hand's motion and noise.
    acc = r.inv().apply([0.0, 0.0, 1.0]) + rng.normal(0, 0.02 * noise, (n, 3))

    # EMG: task pattern, demo gain, grasp activation over the phase, noisy raw samples.
    gain = np.exp(rng.normal(0, EMG_GAIN_LOG_STD * noise, 8))
    act = 0.35 + 0.65 * min_jerk(phase / 0.12) - 0.35 * min_jerk((phase - 0.6) / 0.4)
    prof = s.defs["rest"][k] + (s.defs["active"][k] - s.defs["rest"][k]) * act[:, None]
    raw = np.abs(prof * gain * (1.0 + rng.normal(0, EMG_RAW_NOISE * noise, (n, 8))))
    emg = emg_envelope(raw, dt, s.emg_cutoff_hz)

    # Robot: minimum-jerk from the start to the demo's hand-over configuration q1.
    q0 = START_Q_RAD + rng.normal(0, 0.005 * noise, 7)
    a, b = rng.uniform(0.02, 0.08), rng.uniform(0.80, 0.90)
    s_r = min_jerk((phase - a) / (b - a))
    q = q0 + s_r[:, None] * (q1 - q0)

    # Human hand: from in front of the torso to beside the robot's hand-over point, slight arc.
    h1 = s.defs["point"][k] + offset + HAND_FROM_GRIPPER_M + rng.normal(0, 0.01 * noise, 3)
    h0 = HAND_START_M + rng.normal(0, 0.03 * noise, 3)
    arc = np.array([0.0, 0.0, 0.10]) * np.sin(np.pi * s_h)[:, None]
    hand = h0 + s_h[:, None] * (h1 - h0) + arc + rng.normal(0, 0.003 * noise, (n, 3))
    return Demo(
        task=task,
        name=f"{task}_{i:03d}",
        source=f"synthetic(seed={s.seed})/{task}/{i}",
        t=t,
        groups={"orientation": quat, "emg": emg, "acc": acc, ROBOT: q},
        channel_names={
            "orientation": ORIENTATION.channels,
            "emg": EMG.channels,
            "acc": ACC.channels,
            ROBOT: JOINT_NAMES,
        },
        extras={"hand_position": hand, "handover_offset": np.tile(offset, (n, 1))},
        duration_s=float(t[-1]),
    )
