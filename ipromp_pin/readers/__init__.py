"""Readers of hand-over demonstrations: :func:`load_dataset` and :func:`read_demo`.

A dataset is a folder with one sub-folder per task (task = sub-folder name).
Each task folder is in one of these formats, detected per folder when
``format="auto"`` (first match wins):

* ``"chen2017"``: the chen2017_handover per-topic CSV export
  (``csv/<stamp>-myo_raw_emg_pub.csv`` ...), see :mod:`.chen2017`;
* ``"multimodal"``: ``csv/<stamp>/multiModal_states.csv`` (handover_20171128),
  see :mod:`.multimodal`;
* ``"native"``: the project's own format, one ``.npz`` or ``.csv`` per demo,
  see :mod:`.native`;
* ``"bag"``: ROS1 bags ``<stamp>.bag`` of the chen2017 topics, see :mod:`.rosbag`;
* ``"rosbag2"``: ROS 2 recordings, one rosbag2 folder ``<stamp>/`` (``metadata.yaml`` with MCAP or
  SQLite storage) or ``<stamp>.mcap`` / ``<stamp>.db3`` file per demo, see :mod:`.rosbag2`.

A chen2017 task folder holds both the CSV export and the bags; ``"auto"`` reads
the CSVs (faster), ``format="bag"`` the bags (the same demos, see the tests).

Single recordings without a task label (a new recording to plan from): :func:`read_recording`
reads one file or folder in any of these formats into a :class:`~ipromp_pin.data.Demo` whose task
is :data:`UNKNOWN_TASK` (``""``), and :func:`expand_recordings` lists the recordings that files and
folders hold (:mod:`.recordings`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from ..data import ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ
from . import chen2017, multimodal, native, plausibility, rosbag, rosbag2
from .native import write_dataset, write_demo
from .recordings import UNKNOWN_TASK, expand_recordings, recording_format
from .streams import BAXTER_LEFT_JOINTS

FORMATS = ("auto", "chen2017", "multimodal", "bag", "native", "rosbag2")
"""Accepted values of ``format``."""

__all__ = [
    "BAXTER_LEFT_JOINTS",
    "FORMATS",
    "UNKNOWN_TASK",
    "count_demos",
    "detect_format",
    "expand_recordings",
    "list_demos",
    "load_dataset",
    "plausibility",
    "read_demo",
    "read_recording",
    "recording_format",
    "write_dataset",
    "write_demo",
]


def detect_format(folder: Path) -> str:
    """Format of a task folder: ``"chen2017"``, ``"multimodal"``, ``"native"``, ``"bag"`` or ``"rosbag2"``.

    Raises:
        DataError: the folder holds none of them.
    """
    folder = Path(folder)
    if chen2017.is_chen2017_folder(folder):
        return "chen2017"
    if multimodal.is_multimodal_folder(folder):
        return "multimodal"
    if native.is_native_folder(folder):
        return "native"
    if rosbag.is_bag_folder(folder):
        return "bag"
    if rosbag2.is_rosbag2_folder(folder):
        return "rosbag2"
    raise DataError(
        folder,
        "format",
        "cannot detect the format: no csv/<stamp>-myo_raw_emg_pub.csv, csv/<stamp>/multiModal_states.csv, "
        "*.npz / *.csv demo files, *.bag files or rosbag2 recordings (<stamp>/metadata.yaml, *.mcap, *.db3)",
    )


def list_demos(folder: Path, format: str, order: str = "config") -> list[Path]:
    """Demo paths of a task folder in demo order (see each reader's ``list_demos``)."""
    if format == "chen2017":
        return chen2017.list_demos(folder, order)
    if format == "multimodal":
        return multimodal.list_demos(folder, order)
    if format == "native":
        return native.list_demos(folder, order)
    if format == "bag":
        return rosbag.list_demos(folder, order)
    if format == "rosbag2":
        return rosbag2.list_demos(folder, order)
    raise DataError(folder, "format", f"unknown format {format!r} (use one of {', '.join(FORMATS)})")


def read_demo(
    path: str | Path,
    task: str | None = None,
    *,
    format: str = "auto",
    frames: Sequence[str] | None = None,
    rate_hz: float | None = 50.0,
    robot_joints: Sequence[str] | None = None,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
    topics: Mapping[str, str] | None = None,
) -> Demo:
    """Read one demonstration and check that its values are physically plausible.

    Args:
        path: The demo: a chen2017 ``<task>/csv/<stamp>`` prefix or one of its CSV files,
            a ``multiModal_states.csv`` (or its folder), a ``.bag``, a rosbag2 folder or
            ``.mcap``/``.db3`` file, or a native ``.npz``/``.csv``
            (:func:`~.recordings.recording_format`).
        task: Task name (default: derived from the path).
        format: One of :data:`FORMATS`.
        frames: Skeleton frames (child_frame_id, e.g. ``"/left_hand_1"``) to read as
            human groups (multimodal and rosbag2 formats; native demos must contain them; an
            error for chen2017 recordings, which have none).
        rate_hz: Output sampling rate in [Hz] (native demos are resampled when theirs differs;
            ``None`` keeps a native demo's rate).
        robot_joints: Joint names of the ``"robot"`` group, in the wanted order (default: a native
            file's own joints as written; the recorded formats, whose default topics are those of
            Baxter's experiments, Baxter's left arm, :data:`BAXTER_LEFT_JOINTS`).
        emg_cutoff_hz: EMG envelope cut-off in [Hz] (recorded formats).
        joint_limits: Recorded joint name -> (lower, upper) in [rad]: the robot's limits, which the
            recorded angles must respect (see :mod:`.plausibility`; default: a generic bound).
        end_effector: Forward kinematics of the robot group, (T, J) [rad] -> (T, 3) [m] in the base
            frame; used by the multimodal and rosbag2 readers to find the human's handing hand when the
            robot's end-point stream was not recorded.
        topics: Stream -> topic, replacing the default topics of the ``bag`` and ``rosbag2``
            readers (:data:`.rosbag2.DEFAULT_TOPICS`; rosbag2 also ``"frame:<name>"``); an error for
            the other formats.

    Returns:
        The demo on a uniform time grid starting at 0.

    Raises:
        DataError: unreadable, malformed or implausible data (see :mod:`.plausibility`), naming the
            file, the field and the problem.
    """
    path = Path(path)
    if format not in FORMATS:
        raise DataError(path, "format", f"unknown format {format!r} (use one of {', '.join(FORMATS)})")
    if format == "auto":
        format = recording_format(path)
    if frames and format in ("chen2017", "bag"):
        raise DataError(
            path, "frames", f"the {format} recordings have no tracked frames (asked for {list(frames)})"
        )
    if topics and format not in ("bag", "rosbag2"):
        raise DataError(path, "topics", f"the {format} recordings have no topics to choose")
    if topics and format == "bag" and not set(topics) <= set(rosbag.DEFAULT_TOPICS):
        unknown = sorted(set(topics) - set(rosbag.DEFAULT_TOPICS))
        raise DataError(
            path, "topics", f"unknown stream {unknown[0]!r} (use {', '.join(rosbag.DEFAULT_TOPICS)})"
        )
    # The recordings' readers resample at 50 Hz by default; a native file keeps its own rate.
    rate = 50.0 if rate_hz is None else rate_hz
    recorded = BAXTER_LEFT_JOINTS if robot_joints is None else robot_joints
    if format == "chen2017":
        demo = chen2017.read_demo(
            path, task, rate_hz=rate, robot_joints=recorded, emg_cutoff_hz=emg_cutoff_hz
        )
    elif format == "multimodal":
        demo = multimodal.read_demo(
            path,
            task,
            frames=frames,
            rate_hz=rate,
            robot_joints=recorded,
            emg_cutoff_hz=emg_cutoff_hz,
            end_effector=end_effector,
        )
    elif format == "bag":
        demo = rosbag.read_demo(
            path, task, rate_hz=rate, robot_joints=recorded, emg_cutoff_hz=emg_cutoff_hz, topics=topics
        )
    elif format == "rosbag2":
        demo = rosbag2.read_demo(
            path,
            task,
            frames=frames,
            rate_hz=rate,
            robot_joints=recorded,
            emg_cutoff_hz=emg_cutoff_hz,
            end_effector=end_effector,
            topics=topics,
        )
    else:
        demo = native.read_demo(path, task, rate_hz=rate_hz, frames=frames, robot_joints=robot_joints)
    return plausibility.check_demo(demo, joint_limits)


def read_recording(
    path: str | Path,
    *,
    frames: Sequence[str] | None = None,
    rate_hz: float | None = 50.0,
    robot_joints: Sequence[str] | None = None,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
    topics: Mapping[str, str] | None = None,
) -> Demo:
    """Read ONE recording of an unknown task, its format detected (:mod:`.recordings`).

    Args:
        path: A file, or a folder holding one recording: a ``multiModal_states.csv`` (or its
            folder), a ROS 1 ``.bag``, a rosbag2 folder or ``.mcap`` / ``.db3`` file, a native
            ``.npz`` / ``.csv``, or one chen2017 export stamp (any of its ``<stamp>-<topic>.csv``
            files, their prefix, or a folder holding only that stamp's files).
        frames, rate_hz, robot_joints, emg_cutoff_hz, joint_limits, end_effector, topics: As
            :func:`read_demo`.

    Returns:
        The demo, with ``task`` :data:`UNKNOWN_TASK` (``""``: the recording's folder names no task,
        and a label stored in a native file is not used) and ``name`` the recording's (its stamp,
        folder or file name).

    Raises:
        DataError: nothing there, not a recording, a folder of several recordings (list them with
            :func:`expand_recordings`), or bad data (as :func:`read_demo`), naming the file, field and
            problem.
    """
    found = expand_recordings([path])
    if len(found) != 1:
        raise DataError(
            path,
            None,
            f"holds {len(found)} recordings, not one (name one of them, e.g. {found[0]}; or list them with "
            "expand_recordings)",
        )
    return read_demo(
        found[0],
        UNKNOWN_TASK,
        format=recording_format(found[0]),
        frames=frames,
        rate_hz=rate_hz,
        robot_joints=robot_joints,
        emg_cutoff_hz=emg_cutoff_hz,
        joint_limits=joint_limits,
        end_effector=end_effector,
        topics=topics,
    )


def _check_readable(folder: Path) -> None:
    """Raise DataError when ``folder`` (or its ``csv`` sub-folder) cannot be listed."""
    for d in (folder, folder / "csv"):
        if d is not folder and not d.is_dir():
            continue
        try:
            with os.scandir(d) as entries:
                next(entries, None)
        except OSError as exc:
            raise DataError(d, None, f"cannot read the task folder: {exc.strerror or exc}") from None
        if not os.access(d, os.R_OK | os.X_OK):
            raise DataError(d, None, "cannot read the task folder: permission denied")


def _dataset_plan(root: Path, format: str, order: str) -> list[tuple[str, str, list[Path]]]:
    """(task, format, demo files) of every task folder of a dataset, without reading a demo."""
    if not root.is_dir():
        raise DataError(root, None, "dataset folder not found")
    if format not in FORMATS:
        raise DataError(root, "format", f"unknown format {format!r} (use one of {', '.join(FORMATS)})")
    try:
        entries = sorted(p for p in root.iterdir() if not p.name.startswith((".", "_")))
    except OSError as exc:
        raise DataError(root, None, f"cannot read the dataset folder: {exc.strerror or exc}") from None
    for p in entries:
        if p.is_symlink() and not p.exists():
            raise DataError(p, None, "broken link where a task folder was expected")
    subdirs = [p for p in entries if p.is_dir()]
    plan: list[tuple[str, str, list[Path]]] = []
    for d in subdirs:
        _check_readable(d)
        if format == "auto":
            try:
                fmt = detect_format(d)
            except DataError as exc:
                raise DataError(
                    d,
                    "format",
                    f"{exc.problem}; a task folder must hold demos (rename the folder with a leading '_' "
                    "to leave it out)",
                ) from None
        else:
            fmt = format
        plan.append((d.name, fmt, list_demos(d, fmt, order)))
    if not plan:
        raise DataError(root, None, "no task sub-folders (expected one folder of demos per task)")
    for task, _, files in plan:
        if len(files) < 2:
            raise DataError(root / task, None, f"a task needs at least 2 demos, found {len(files)}")
    return plan


def count_demos(path: str | Path, *, format: str = "auto") -> dict[str, int]:
    """Number of demos of every task of a dataset folder, found without reading them (fast).

    Raises:
        DataError: as :func:`load_dataset` before it reads a demo.
    """
    return {task: len(files) for task, _, files in _dataset_plan(Path(path), format, "recorded")}


def load_dataset(
    path: str | Path,
    *,
    format: str = "auto",
    frames: Sequence[str] | None = None,
    rate_hz: float = 50.0,
    robot_joints: Sequence[str] | None = None,
    order: str = "config",
    progress: Callable[[int, int, str], None] | None = None,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Dataset:
    """Load a dataset: a folder with one sub-folder per task.

    Args:
        path: The dataset folder: every sub-folder is a task, except hidden ones and those whose
            name starts with ``_`` (a sub-folder without demos is an error, not a task that
            silently disappears).
        format: One of :data:`FORMATS`; ``"auto"`` detects it per task folder.
        frames: Skeleton frames to read as human groups (multimodal format).
        rate_hz: Output sampling rate in [Hz].
        order: ``"config"`` (the authors' cfg order when there is one) or ``"recorded"`` (by stamp).
        progress: Optional ``callable(done, total, name)`` called after each demo.
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
        robot_joints, joint_limits, end_effector: See :func:`read_demo`; by default every demo's
            robot group has the first demo's joints, in its order (matched by name).

    Returns:
        Dataset with tasks in sorted folder-name order.

    Raises:
        DataError: no task sub-folder, a sub-folder that cannot be read, a file where a task folder
            is expected (a broken link), undetectable format, a task with fewer than 2 demos, any
            bad or implausible demo, or a demo whose duration is an outlier of its task (naming
            its file).
    """
    root = Path(path)
    plan = _dataset_plan(root, format, order)
    total = sum(len(files) for _, _, files in plan)
    done = 0
    demos: dict[str, list[Demo]] = {}
    joints = robot_joints
    for task, fmt, files in plan:
        out = demos.setdefault(task, [])
        for f in files:
            out.append(
                read_demo(
                    f,
                    task,
                    format=fmt,
                    frames=frames,
                    rate_hz=rate_hz,
                    robot_joints=joints,
                    emg_cutoff_hz=emg_cutoff_hz,
                    joint_limits=joint_limits,
                    end_effector=end_effector,
                )
            )
            if joints is None and ROBOT in out[-1].groups:  # the others' joints in the first demo's order
                joints = out[-1].channel_names[ROBOT]
            done += 1
            if progress is not None:
                progress(done, total, f"{task}/{out[-1].name}")
    plausibility.check_durations(demos)
    return Dataset(root=str(root), demos=demos)
