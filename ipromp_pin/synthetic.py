"""Synthetic hand-over demonstrations with known ground truth.

:func:`make_synthetic_dataset` mimics the chen2017 recordings: a human hands an
object to Baxter's left arm while wearing a Myo armband.

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
* The robot group holds Baxter left-arm joint angles moving from the measured
  start configuration to a task-specific hand-over configuration along a
  minimum-jerk profile, inside Baxter's joint limits.
* ``extras["hand_position"]`` is a human hand path in the Baxter base frame
  [m], ending just in front of the robot's measured hand-over point.

Everything is deterministic for a given ``seed``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .data import ROBOT, Dataset, Demo
from .exceptions import DataError
from .preprocess import DEFAULT_EMG_CUTOFF_HZ, emg_envelope, quaternion_continuity

NOMINAL_DURATION_S = 3.3
"""Nominal demo duration in [s]; a demo's true phase ratio is ``duration_s / NOMINAL_DURATION_S``."""
nominal_duration_s = NOMINAL_DURATION_S
"""Alias of :data:`NOMINAL_DURATION_S`."""

DURATION_RANGE_S = (2.5, 4.2)
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

# Measured on the real chen2017_handover recordings (all 99 demos, read with
# ipromp_pin.readers.load_dataset at 50 Hz): median of the first sample of the robot
# group (the start is the same for all three tasks, std < 0.015 rad).
START_Q_RAD = np.array([-0.838, -0.969, 0.377, 1.262, -0.204, 1.189, 1.662])
"""Start configuration [rad] (median first sample of the real demos)."""

# Median of the last sample of the robot group per task (the hand-over pose), and the
# across-demo standard deviation of that last sample, same recordings.
TASKS = ("rod", "wrench", "tape")
"""Names of the first three synthetic tasks (modelled on aluminum_hold, spanner_handover, tape_hold)."""
HANDOVER_Q_RAD = np.array(
    [
        [-1.466, -0.559, 0.363, 0.618, -0.538, 1.001, 1.514],  # aluminum_hold
        [-1.593, -0.445, 0.425, 0.519, -0.326, 1.256, 1.016],  # spanner_handover
        [-1.439, -0.526, 0.371, 0.812, -0.594, 0.745, 1.398],  # tape_hold
    ]
)
"""Task hand-over configurations [rad] (median last sample of the real demos per task)."""
HANDOVER_Q_STD_RAD = np.array([0.06, 0.05, 0.03, 0.15, 0.11, 0.26, 0.19])
"""Across-demo std of the hand-over configuration [rad] (mean of the three tasks' std)."""
HANDOVER_POINT_M = np.array([[0.868, -0.302, 0.175], [0.785, -0.289, 0.099], [0.918, -0.264, 0.127]])
"""Robot end-point position at hand-over [m] in the base frame (median last endpoint_state per task)."""

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

HAND_START_M = np.array([1.35, -0.45, -0.20])
"""Human hand start position [m] in the Baxter base frame (in front of the robot, hand lowered)."""
HAND_BEYOND_GRIPPER_M = np.array([0.08, 0.0, 0.0])
"""The hand ends this far from the robot's hand-over point (the object lies in between), in [m]."""


def true_alpha(demo: Demo) -> float:
    """Ground-truth phase ratio of a synthetic demo: ``duration_s / NOMINAL_DURATION_S``."""
    return float(demo.duration_s) / NOMINAL_DURATION_S


def min_jerk(x: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 10x^3 - 15x^4 + 6x^5 on x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def _task_definitions(n_tasks: int) -> dict[str, np.ndarray | list[str]]:
    """Task parameters; tasks beyond the measured three are fixed blends of them."""
    names = list(TASKS[:n_tasks])
    q_end = list(HANDOVER_Q_RAD[:n_tasks])
    point = list(HANDOVER_POINT_M[:n_tasks])
    rest = list(EMG_REST[:n_tasks])
    active = list(EMG_ACTIVE[:n_tasks])
    extra_rng = np.random.default_rng(12345)  # fixed: task definitions do not depend on the seed
    for k in range(3, n_tasks):
        w = extra_rng.dirichlet(np.ones(3))
        names.append(f"task{k}")
        q_end.append(w @ HANDOVER_Q_RAD + extra_rng.normal(0.0, 0.05, 7))
        point.append(w @ HANDOVER_POINT_M)
        perm = extra_rng.permutation(8)
        rest.append((w @ EMG_REST)[perm])
        active.append((w @ EMG_ACTIVE)[extra_rng.permutation(8)] * extra_rng.uniform(0.8, 1.3))
    lo, hi = BAXTER_LEFT_LIMITS_RAD[:, 0] + LIMIT_MARGIN_RAD, BAXTER_LEFT_LIMITS_RAD[:, 1] - LIMIT_MARGIN_RAD
    return {
        "names": names,
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

    Returns:
        Dataset with groups ``"orientation"`` (4), ``"emg"`` (8), ``"acc"`` (3)
        and ``"robot"`` (7 Baxter left-arm joints), plus ``extras["hand_position"]``
        (T, 3) in [m]. ``root`` is ``"synthetic(seed=...)"``.
    """
    if int(n_tasks) < 1:
        raise DataError("synthetic", "n_tasks", f"must be >= 1, got {n_tasks}")
    if int(n_demos) < 2:
        raise DataError("synthetic", "n_demos", f"must be >= 2, got {n_demos}")
    if not (np.isfinite(rate_hz) and rate_hz >= 10.0):
        raise DataError("synthetic", "rate_hz", f"must be >= 10 Hz, got {rate_hz}")
    if not (np.isfinite(noise) and noise >= 0):
        raise DataError("synthetic", "noise", f"must be >= 0, got {noise}")
    rng = np.random.default_rng(seed)
    defs = _task_definitions(int(n_tasks))
    r_start = Rotation.from_quat(np.roll(ORIENTATION_START_WXYZ, -1))
    r_end = Rotation.from_quat(np.roll(ORIENTATION_END_WXYZ, -1))
    lo, hi = BAXTER_LEFT_LIMITS_RAD[:, 0] + LIMIT_MARGIN_RAD, BAXTER_LEFT_LIMITS_RAD[:, 1] - LIMIT_MARGIN_RAD
    dt = 1.0 / rate_hz
    demos: dict[str, list[Demo]] = {}
    for k, task in enumerate(defs["names"]):
        # Task-specific small tilt of the end orientation about a fixed axis per task.
        axis = np.array([np.cos(2.1 * k), np.sin(2.1 * k), 0.3])
        tilt = Rotation.from_rotvec(np.deg2rad(TASK_ORIENTATION_TILT_DEG) * k * axis / np.linalg.norm(axis))
        out = demos[task] = []
        for i in range(int(n_demos)):
            duration = rng.uniform(*DURATION_RANGE_S)
            n = int(round(duration * rate_hz)) + 1
            t = dt * np.arange(n)
            phase = t / t[-1]

            # Human forearm orientation: shared path, demo-to-demo variation, sensor noise.
            jitter0 = Rotation.from_rotvec(rng.normal(0, np.deg2rad(4.0) * noise, 3))
            jitter1 = Rotation.from_rotvec(rng.normal(0, np.deg2rad(4.0) * noise, 3))
            ra, rb = jitter0 * r_start, jitter1 * tilt * r_end
            rel = (ra.inv() * rb).as_rotvec()
            s_h = min_jerk((phase - rng.uniform(0.0, 0.05)) / rng.uniform(0.7, 0.8))
            r = ra * Rotation.from_rotvec(s_h[:, None] * rel[None, :])
            r = Rotation.from_rotvec(rng.normal(0, 0.004 * noise, (n, 3))) * r
            quat = quaternion_continuity(np.roll(r.as_quat(), 1, axis=1))
            if quat[0, 0] < 0:
                quat = -quat
            # Accelerometer: gravity in the sensor frame [g] plus the hand's motion and noise.
            acc = r.inv().apply([0.0, 0.0, 1.0]) + rng.normal(0, 0.02 * noise, (n, 3))

            # EMG: task pattern, demo gain, grasp activation over the phase, noisy raw samples.
            gain = np.exp(rng.normal(0, 0.15 * noise, 8))
            act = 0.35 + 0.65 * min_jerk(phase / 0.12) - 0.35 * min_jerk((phase - 0.6) / 0.4)
            prof = defs["rest"][k] + (defs["active"][k] - defs["rest"][k]) * act[:, None]
            raw = np.abs(prof * gain * (1.0 + rng.normal(0, 0.25 * noise, (n, 8))))
            emg = emg_envelope(raw, dt, emg_cutoff_hz)

            # Robot: minimum-jerk from the start to a demo-specific hand-over configuration.
            q0 = START_Q_RAD + rng.normal(0, 0.005 * noise, 7)
            q1 = np.clip(defs["q_end"][k] + rng.normal(0, 0.5 * noise, 7) * HANDOVER_Q_STD_RAD, lo, hi)
            a, b = rng.uniform(0.02, 0.08), rng.uniform(0.80, 0.90)
            s_r = min_jerk((phase - a) / (b - a))
            q = q0 + s_r[:, None] * (q1 - q0)

            # Human hand: from its start to just in front of the robot's hand-over point, slight arc.
            h1 = defs["point"][k] + HAND_BEYOND_GRIPPER_M + rng.normal(0, 0.02 * noise, 3)
            h0 = HAND_START_M + rng.normal(0, 0.03 * noise, 3)
            arc = np.array([0.0, 0.0, 0.10]) * np.sin(np.pi * s_h)[:, None]
            hand = h0 + s_h[:, None] * (h1 - h0) + arc + rng.normal(0, 0.003 * noise, (n, 3))

            out.append(
                Demo(
                    task=task,
                    name=f"{task}_{i:03d}",
                    source=f"synthetic(seed={seed})/{task}/{i}",
                    t=t,
                    groups={"orientation": quat, "emg": emg, "acc": acc, ROBOT: q},
                    channel_names={
                        "orientation": ("qw", "qx", "qy", "qz"),
                        "emg": tuple(f"emg{c}" for c in range(8)),
                        "acc": ("ax", "ay", "az"),
                        ROBOT: JOINT_NAMES,
                    },
                    extras={"hand_position": hand},
                    duration_s=float(t[-1]),
                )
            )
    return Dataset(root=f"synthetic(seed={seed})", demos=demos)
