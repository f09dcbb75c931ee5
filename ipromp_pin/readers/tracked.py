"""Tracked frames of a recording: a skeleton tracker's body frames and the robot's gripper frame.

Shared by the readers of recordings with tracked frames (:mod:`.multimodal`: the ``tf_of_interest``
transforms of ``multiModal_states.csv``; :mod:`.rosbag2`: ``tf2_msgs/msg/TFMessage`` topics). A
reader gives each tracked frame as a :class:`FrameTrack`: its positions x, y, z [m] in the robot's
base frame at times on the recording PC's clock, NaN where the frame was not listed or its
transform was all zeros (a look-up that returned nothing). From there every reader does the same:

* a position farther than :data:`JUMP_THRESHOLD_M` from the component-wise median of the
  :data:`JUMP_WINDOW` valid samples centred on it is a jump (an isolated spike of at most 2
  samples; the tracker's genuine catch-up steps after a stall persist and are kept) and missing;
* a requested frame (``frames=["/left_hand_1"]``) becomes a group of positions (``Demo.missing``
  where a neighbouring source sample is missing, :func:`frame_groups`);
* every skeleton frame (``child_frame_id`` starting with ``/``, not the gripper) becomes the extra
  ``"skeleton:<frame>"`` (T, 3), NaN where missing: the human body of the safety checks
  (:mod:`ipromp_pin.human.body`);
* the extra ``"hand_position"`` (T, 3) is the hand frame (:data:`HAND_FRAMES`) that ends closest to
  the robot's gripper (the end-point, else a tracked gripper frame :data:`GRIPPER_FRAMES`, else
  the forward kinematics of the joints), gaps linearly filled (:func:`frame_extras`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..data import ROBOT
from ..exceptions import DataError
from ..signals.checks import POSITION_BOUND_M, check_norms
from ..signals.groups import SKELETON_FRAME as FRAME
from ..signals.preprocess import Stream

JUMP_THRESHOLD_M = 0.25
"""A tracked position farther than this from the median of its neighbours is a jump (missing), in [m]."""
JUMP_WINDOW = 5
"""Number of valid samples (centred) whose median a tracked position is compared with."""
HAND_FRAMES = ("/left_hand_1", "/right_hand_1")
"""The human's hand frames, one of which hands the object over."""
SKELETON_EXTRA = "skeleton:"
"""Prefix of the extras holding every tracked skeleton frame (``"skeleton:/head_1"`` ...): positions
(T, 3) [m], NaN where the frame is not listed, all-zero or a jump (the body model of
:mod:`ipromp_pin.human.body` reads them; they are not modelled)."""
GRIPPER_FRAMES = ("left_gripper", "/left_gripper")
"""Tracked frames at the robot's end-point (the tf of Baxter's left gripper), used to choose the
handing hand when the end-point stream was not recorded."""
STREAM_PREFIX = "frame:"
"""Prefix of the tracked frames' stream names in :func:`frame_streams` (``"frame:/left_hand_1"``)."""


@dataclass(frozen=True)
class FrameTrack:
    """One tracked frame as recorded.

    Attributes:
        t: Sample times in [s] on the recording PC's clock, shape (N,).
        positions: Positions x, y, z in [m] in the robot's base frame, shape (N, 3); NaN where the
            frame was not listed or its transform was all zeros.
    """

    t: np.ndarray
    positions: np.ndarray


@dataclass(frozen=True)
class TrackedTopic:
    """Tracked frames of one topic as recorded: one sample per message.

    Attributes:
        header_s: Header stamps in [s] (sender clock), shape (N,).
        receive_s: Receive times in [s] (recording PC), shape (N,).
        positions: Frame -> positions x, y, z (N, 3) in [m] in the robot's base frame; NaN in the
            messages that do not list the frame or list it as all zeros.
        source: Where it came from (file and topic), for error messages.
    """

    header_s: np.ndarray
    receive_s: np.ndarray
    positions: dict[str, np.ndarray]
    source: str


def is_skeleton_frame(frame: str) -> bool:
    """Whether ``frame`` (a ``child_frame_id``) is a skeleton frame: starts with ``/``, not the gripper."""
    return frame.startswith("/") and frame not in GRIPPER_FRAMES


def flag_jumps(
    pos: np.ndarray, threshold_m: float = JUMP_THRESHOLD_M, window: int = JUMP_WINDOW
) -> np.ndarray:
    """Mask (N,) of tracked positions (N, 3) farther than ``threshold_m`` from the median of the
    ``window`` valid samples centred on them (isolated spikes); NaN rows are not flagged."""
    valid = np.flatnonzero(np.all(np.isfinite(pos), axis=1))
    out = np.zeros(pos.shape[0], dtype=bool)
    if valid.size < 3:
        return out
    v = pos[valid]
    h = window // 2
    padded = np.concatenate([np.repeat(v[:1], h, 0), v, np.repeat(v[-1:], h, 0)])
    windows = np.stack([padded[i : i + v.shape[0]] for i in range(window)], axis=0)
    med = np.median(windows, axis=0)
    out[valid] = np.linalg.norm(v - med, axis=1) > threshold_m
    return out


def needed_frames(frames: Sequence[str], skeleton: Sequence[str], with_gripper: bool) -> list[str]:
    """The frames a reader turns into streams, in stream order: the requested ``frames``, the hand
    frames, (``with_gripper``) the gripper frames, then the recording's ``skeleton`` frames."""
    gripper = list(GRIPPER_FRAMES) if with_gripper else []
    return list(dict.fromkeys(list(frames) + list(HAND_FRAMES) + gripper + list(skeleton)))


def frame_streams(
    source: object,
    tracks: Mapping[str, FrameTrack],
    frames: Sequence[str],
    reserved: set[str],
    with_gripper: bool,
    available: Sequence[str],
) -> dict[str, Stream]:
    """Streams ``"frame:<f>"`` of the requested frames, the hand frames, (``with_gripper``) the
    gripper frames and every skeleton frame of ``tracks``; jumps and untracked samples missing.

    Args:
        source: File for error messages.
        tracks: Frame -> its track (at least every frame of :func:`needed_frames` that was tracked).
        frames: The requested frames (each must be tracked, with at least 2 valid samples).
        reserved: Stream names a frame may not take (the recording's other streams).
        with_gripper: Whether the gripper frames are read (when the end-point was not recorded).
        available: The recording's frame names, for the error naming an untracked requested frame.

    Raises:
        DataError: a requested frame clashes with a stream name, was never tracked or has fewer than
            2 valid samples; a position beyond the plausible bound.
    """
    for f in frames:
        if f in reserved:
            raise DataError(source, f, "frame name clashes with a channel group name")
    skeleton = sorted(f for f in tracks if is_skeleton_frame(f))
    out = {}
    for f in needed_frames(frames, skeleton, with_gripper):
        track = tracks.get(f)
        if track is None:
            if f in frames:
                raise DataError(source, f, f"frame never tracked (child_frame_ids: {', '.join(available)})")
            continue
        p = np.array(track.positions, dtype=float)
        check_norms(source, f, p, 0.0, POSITION_BOUND_M, "m", what="row")
        p[flag_jumps(p)] = np.nan
        if np.sum(np.all(np.isfinite(p), axis=1)) < 2:
            if f in frames:
                raise DataError(source, f, "fewer than 2 valid samples of the frame")
            continue
        out[STREAM_PREFIX + f] = Stream(
            track.t, p, FRAME.channels, FRAME.raw_kind, str(source), allow_missing=True
        )
    return out


def frame_groups(
    source: object, values: dict[str, np.ndarray], frames: Sequence[str]
) -> tuple[dict[str, np.ndarray], dict[str, tuple[str, ...]], dict[str, np.ndarray]]:
    """The requested frames' groups from the aligned streams: (groups, channel names, missing masks).

    Raises:
        DataError: a frame missing over the whole demo.
    """
    groups: dict[str, np.ndarray] = {}
    names: dict[str, tuple[str, ...]] = {}
    missing: dict[str, np.ndarray] = {}
    for f in frames:
        v = values[STREAM_PREFIX + f]
        groups[f] = v
        names[f] = FRAME.channels
        m = ~np.all(np.isfinite(v), axis=1)
        if m.all():
            raise DataError(source, f, "frame missing over the whole demo")
        v[m] = np.nan
        if m.any():
            missing[f] = m
    return groups, names, missing


def _fill_gaps(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    ok = np.all(np.isfinite(x), axis=1)
    if ok.all() or ok.sum() < 2:
        return x
    return np.stack([np.interp(t, t[ok], x[ok, j]) for j in range(x.shape[1])], axis=1)


def _hand_position(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    reference: np.ndarray | None,
) -> np.ndarray | None:
    """The hand frame that ends closest to ``reference`` (T, 3) [m], gaps filled; None without one."""
    best, best_d = None, np.inf
    for f in HAND_FRAMES:
        v = values.get(STREAM_PREFIX + f)
        if v is None or reference is None:
            continue
        tail = slice(int(0.8 * t.size), None)
        d = np.linalg.norm(v[tail] - reference[tail], axis=1)
        d = float(np.nanmedian(d)) if np.any(np.isfinite(d)) else np.inf
        if d < best_d:
            best, best_d = v, d
    if best is not None and np.sum(np.all(np.isfinite(best), axis=1)) >= 2:
        return _fill_gaps(t, best)
    return None


def _gripper_reference(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    extras: dict[str, np.ndarray],
    end_effector: Callable[[np.ndarray], np.ndarray] | None,
) -> np.ndarray | None:
    """Where the robot's gripper is (T, 3) [m]: the end-point, else a tracked gripper frame, else the
    forward kinematics ``end_effector`` of the joints; None without any."""
    if "endpoint_pose" in extras:
        return extras["endpoint_pose"][:, :3]
    for f in GRIPPER_FRAMES:
        v = values.get(STREAM_PREFIX + f)
        if v is not None and np.any(np.all(np.isfinite(v[int(0.8 * t.size) :]), axis=1)):
            return v
    if end_effector is not None:
        return np.asarray(end_effector(values[ROBOT]), dtype=float).reshape(t.size, 3)
    return None


def frame_extras(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    extras: dict[str, np.ndarray],
    end_effector: Callable[[np.ndarray], np.ndarray] | None,
) -> None:
    """Add the ``"skeleton:<frame>"`` extras and (when a hand and a gripper reference are known)
    ``"hand_position"`` to ``extras``, from the aligned streams ``values`` on the grid ``t`` [s]."""
    for name, v in values.items():
        if name.startswith(STREAM_PREFIX + "/") and name[len(STREAM_PREFIX) :] not in GRIPPER_FRAMES:
            extras[SKELETON_EXTRA + name[len(STREAM_PREFIX) :]] = v
    hand = _hand_position(t, values, _gripper_reference(t, values, extras, end_effector))
    if hand is not None:
        extras["hand_position"] = hand
