"""Reader of the chen2017_handover per-topic CSV export (Myo EMG + IMU, Baxter joints + end-point).

Layout of a task folder (the task name is the folder name)::

    <task>/csv/<stamp>-myo_raw_emg_pub.csv                # .ch0...ch7, ~50 Hz
    <task>/csv/<stamp>-myo_raw_imu_pub.csv                # .quat0..3, .acc0..2 (raw ints), ~50 Hz
    <task>/csv/<stamp>-robot-joint_states.csv             # .name/.position tuple strings, ~100 Hz
    <task>/csv/<stamp>-robot-limb-left-endpoint_state.csv # .pose.position.*, .pose.orientation.*
    <task>/csv/filename_<task>.cfg                        # demo order: one "<stamp>-" per line
    <task>/<stamp>.bag                                    # the original bag (see readers.rosbag)

Every file has ``time`` (the recording PC's receive time as local wall-clock
text) and ``.header.stamp.secs``/``.nsecs``. The robot stamps its messages with
its own clock (about 3.95 s ahead of the PC in these recordings; estimated per
stream and per demo, never assumed) while the PC stamps the Myo messages; see
:func:`ipromp_pin.readers.streams.assemble_recording` for the alignment.

Resulting :class:`~ipromp_pin.data.Demo` groups, on a uniform grid at
``rate_hz`` spanning the streams' overlap, ``t`` from 0:

* ``"orientation"`` (T, 4) ``qw, qx, qy, qz``: the Myo quaternion ``.quat0..3``
  divided by 16384. ``.quat0`` is w: checked on the data, the gravity direction
  predicted by (w = quat0) matches the accelerometer to |cos| = 0.999 on every
  recording, while (w = quat3) gives 0.2-0.8. Unit norm, sign-continuous.
* ``"emg"`` (T, 8) ``emg0..emg7``: envelope (rectified, causal low-pass) of
  ``.ch0..7``, resampled by sample-and-hold so that it stays causal.
* ``"acc"`` (T, 3) ``ax, ay, az``: Myo acceleration in [g] (``.acc0..2`` / 2048).
* ``"robot"`` (T, J): the requested joints in [rad], mapped by name from the
  joint-state messages; messages lacking them (Baxter's one-name gripper
  messages on the same topic) are dropped.
* ``extras["endpoint_pose"]`` (T, 7): end-point position [m] + quaternion xyzw; absent when the
  end-point was not recorded (no ``robot-limb-left-endpoint_state`` file, or one without messages
  or with every stamp 0): it serves calibration only.

Demo order (``order="config"``): the stamps of ``csv/filename_<task>.cfg``;
stamps listed there but without files are skipped with a warning, demos on disk
but not listed are appended in stamp order with a warning. ``order="recorded"``
(or no cfg file): sorted by stamp.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ
from .streams import (
    BAXTER_LEFT_JOINTS,
    CsvTable,
    RawRecording,
    RawStream,
    assemble_recording,
    parse_receive_times,
    select_joint_messages,
)

TOPIC_SUFFIXES = {
    "emg": "myo_raw_emg_pub",
    "imu": "myo_raw_imu_pub",
    "joints": "robot-joint_states",
    "endpoint": "robot-limb-left-endpoint_state",
}
"""Stream -> file-name suffix of its CSV (``<stamp>-<suffix>.csv``)."""

STAMP_RE = re.compile(r"^(\d{4}-\d{2}-\d{2}-\d{2}-\d{2}-\d{2})")
EMG_COLUMNS = [f".ch{i}" for i in range(8)]
IMU_COLUMNS = [".quat0", ".quat1", ".quat2", ".quat3", ".acc0", ".acc1", ".acc2"]
ENDPOINT_COLUMNS = [f".pose.position.{a}" for a in "xyz"] + [f".pose.orientation.{a}" for a in "xyzw"]


def is_chen2017_folder(folder: Path) -> bool:
    """Whether ``folder`` is a chen2017 task folder (has ``csv/*-myo_raw_emg_pub.csv``)."""
    csv_dir = Path(folder) / "csv"
    return csv_dir.is_dir() and any(csv_dir.glob(f"*-{TOPIC_SUFFIXES['emg']}.csv"))


def _stamps_on_disk(csv_dir: Path) -> list[str]:
    stamps = set()
    for p in csv_dir.glob(f"*-{TOPIC_SUFFIXES['emg']}.csv"):
        m = STAMP_RE.match(p.name)
        if m:
            stamps.add(m.group(1))
    return sorted(stamps)


def read_config_order(cfg: Path) -> list[str]:
    """Demo stamps listed in a ``filename_<task>.cfg`` (one ``<stamp>-`` per line), in order."""
    stamps = []
    try:
        lines = cfg.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(cfg, None, f"cannot read: {exc}") from None
    for k, line in enumerate(lines):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        m = STAMP_RE.match(s)
        if not m:
            raise DataError(cfg, f"line {k + 1}", f"{s!r} is not a 'YYYY-MM-DD-HH-MM-SS-' demo stamp")
        stamps.append(m.group(1))
    return stamps


def list_demos(folder: Path, order: str = "config") -> list[Path]:
    """Demo prefixes ``<task>/csv/<stamp>`` of a chen2017 task folder, in demo order.

    Args:
        folder: The task folder.
        order: ``"config"`` (the cfg file's order, when present) or ``"recorded"`` (by stamp).
    """
    folder = Path(folder)
    csv_dir = folder / "csv"
    on_disk = _stamps_on_disk(csv_dir)
    if order not in ("config", "recorded"):
        raise DataError(folder, "order", f"unknown demo order {order!r} (use 'config' or 'recorded')")
    cfg = csv_dir / f"filename_{folder.name}.cfg"
    if order == "config" and cfg.is_file():
        listed = read_config_order(cfg)
        present = set(on_disk)
        missing = [s for s in listed if s not in present]
        if missing:
            warnings.warn(
                f"{cfg}: {len(missing)} listed demos have no CSV files and are skipped: {', '.join(missing)}",
                stacklevel=2,
            )
        seen: set[str] = set()
        stamps: list[str] = []
        for s in listed:
            if s in present and s not in seen:
                seen.add(s)
                stamps.append(s)
        extra = [s for s in on_disk if s not in seen]
        if extra:
            warnings.warn(
                f"{cfg}: {len(extra)} demos on disk are not listed and are appended in stamp order: "
                f"{', '.join(extra)}",
                stacklevel=2,
            )
        stamps += extra
    else:
        stamps = on_disk
    return [csv_dir / s for s in stamps]


def _demo_prefix(path: Path) -> Path:
    """``<task>/csv/<stamp>`` from a prefix or any of the demo's CSV files."""
    path = Path(path)
    m = STAMP_RE.match(path.name)
    if not m:
        raise DataError(path, None, "not a chen2017 demo (expected <task>/csv/<stamp>[-<topic>.csv])")
    return path.parent / m.group(1)


def _header_seconds(table: CsvTable) -> np.ndarray:
    st = table.numbers([".header.stamp.secs", ".header.stamp.nsecs"])
    return st[:, 0] + st[:, 1] * 1e-9


def _read_optional_stream(path: Path, columns: Sequence[str]) -> RawStream | None:
    """The messages of one topic's CSV (None for a file without messages)."""
    table = CsvTable(path)
    if len(table) == 0:
        return None
    values = table.numbers(columns)
    return RawStream(_header_seconds(table), parse_receive_times(path, table.text("time")), values, str(path))


def _read_stream(path: Path, columns: Sequence[str]) -> RawStream:
    """The messages of one topic's CSV, which must hold some (else DataError)."""
    stream = _read_optional_stream(path, columns)
    if stream is None:
        raise DataError(path, None, "stream is empty (no messages)")
    return stream


def _parse_tuple_names(source: object, text: str) -> tuple[str, ...]:
    s = text.strip()
    if len(s) < 2 or s[0] not in "([" or s[-1] not in ")]":
        raise DataError(source, ".name", f"not a tuple of names: {text[:80]!r}")
    return tuple(n.strip().strip("'\"") for n in s[1:-1].split(",") if n.strip())


def _read_joints(path: Path, robot_joints: Sequence[str]) -> RawStream:
    table = CsvTable(path)
    if len(table) == 0:
        raise DataError(path, None, "stream is empty (no messages)")
    name_text = table.text(".name")
    # Few distinct name lists (arm, each gripper): parse each once.
    parsed: dict[str, tuple[str, ...]] = {}
    names_per_msg = []
    for s in name_text:
        n = parsed.get(s)
        if n is None:
            n = parsed[s] = _parse_tuple_names(path, s)
        names_per_msg.append(n)
    keep, cols = select_joint_messages(path, names_per_msg, robot_joints)
    idx = np.flatnonzero(keep)
    pos_text = table.text(".position")
    n_names = len(names_per_msg[idx[0]])
    body = []
    for k in idx:
        s = pos_text[k].strip()
        body.append(s[1:-1].rstrip(", ") if s[:1] in "([" and s[-1:] in ")]" else "corrupt")
    try:
        flat = np.array(",".join(body).split(","), dtype=float)
    except ValueError:
        flat = None
    if flat is None or flat.size != idx.size * n_names:
        for k, s in zip(idx, body, strict=True):
            try:
                p = [float(x) for x in s.split(",")]
            except ValueError:
                p = []
            if len(p) != n_names:
                raise DataError(
                    path,
                    ".position",
                    f"line {k + 2}: expected a tuple of {n_names} numbers, got {pos_text[k][:80]!r}",
                ) from None
        raise DataError(path, ".position", "cannot parse the position tuples")
    pos = flat.reshape(idx.size, n_names)[:, cols]
    header = _header_seconds(table)[idx]
    receive = parse_receive_times(path, table.text("time"))[idx]
    return RawStream(header, receive, pos, str(path))


def read_raw(prefix: Path, robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS) -> RawRecording:
    """The raw streams of one chen2017 demo (``<task>/csv/<stamp>``)."""
    prefix = _demo_prefix(prefix)

    def file(key: str) -> Path:
        return prefix.parent / f"{prefix.name}-{TOPIC_SUFFIXES[key]}.csv"

    endpoint_file = file("endpoint")
    # optional: not recorded in every session
    endpoint = _read_optional_stream(endpoint_file, ENDPOINT_COLUMNS) if endpoint_file.exists() else None
    return RawRecording(
        emg=_read_stream(file("emg"), EMG_COLUMNS),
        imu=_read_stream(file("imu"), IMU_COLUMNS),
        joints=_read_joints(file("joints"), robot_joints),
        endpoint=endpoint,
    )


def read_demo(
    path: Path,
    task: str | None = None,
    *,
    rate_hz: float = 50.0,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
) -> Demo:
    """Read one chen2017 demo.

    Args:
        path: ``<task>/csv/<stamp>`` or any of that demo's CSV files.
        task: Task name (default: the task folder's name).
        rate_hz: Output sampling rate in [Hz].
        robot_joints: Joint names of the robot group, in the wanted order.
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
    """
    prefix = _demo_prefix(Path(path))
    raw = read_raw(prefix, robot_joints)
    return assemble_recording(
        raw,
        task=task if task is not None else prefix.parent.parent.name,
        name=prefix.name,
        source=prefix,
        rate_hz=rate_hz,
        robot_joints=robot_joints,
        emg_cutoff_hz=emg_cutoff_hz,
    )


def clock_offsets(path: Path, robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS) -> dict[str, float]:
    """Estimated clock offset (header stamp minus PC clock) of each stream of a demo, in [s]."""
    raw = read_raw(Path(path), robot_joints)
    assemble_recording(raw, task="", name="", source=path, rate_hz=50.0, robot_joints=robot_joints)
    return dict(raw.clock_offsets_s)
