"""The project's own demo format: one file per demo, ``.npz`` or ``.csv``.

A dataset is a folder with one sub-folder per task; each task folder holds one
file per demo, named ``<demo name>.npz`` or ``<demo name>.csv`` (demos are
ordered by file name). Both forms hold the same content:

* ``t``: sample times in [s], strictly increasing and uniformly spaced (the
  reader shifts them to start at 0; the spacing may deviate by at most 1 %;
  :func:`load_dataset <ipromp_pin.readers.load_dataset>` resamples demos whose
  rate differs from its ``rate_hz``);
* per channel group (``"orientation"``, ``"emg"``, ``"robot"`` or ``"gripper"``, a
  skeleton frame such as ``"/left_hand_1"`` ...): its values (T, D) and channel names, and
  optionally a missing-sample mask (T,) (values there may be NaN; any other
  NaN is an error);
* optional extras: ``endpoint_pose`` (T, 7) (x, y, z [m], quaternion x, y, z, w),
  ``hand_position`` (T, 3) [m], or any other (T, K) array.

The robot side is either ``"robot"`` (joint angles, channels named after the joints) or
``"gripper"`` (a gripper pose path: ``x, y, z`` [m] in the scene frame and a unit quaternion
``qx, qy, qz, qw``, scalar last; read by name in any column order, checked and made
sign-continuous, :mod:`ipromp_pin.signals.gripper`).

Units are those of :class:`~ipromp_pin.data.Demo`: joint angles in [rad],
positions in [m], the orientation a unit quaternion (qw, qx, qy, qz), the EMG
an envelope (readers do not filter native demos again).

``.npz`` (``numpy.savez_compressed``; read with ``allow_pickle=False``, so
only plain numeric and unicode arrays), keys:

=====================  ===========================================================
``format``             ``"ipromp_pin.demo"`` (0-d unicode)
``version``            ``1`` (0-d int)
``task``, ``name``     0-d unicode (the task folder / file name win when they differ)
``duration_s``         0-d float: full duration in [s] (may exceed ``t`` for a partial demo)
``t``                  (T,) float
``groups``             (G,) unicode: group names, in order
``group<i>``           (T, D_i) float: values of ``groups[i]``
``group<i>_channels``  (D_i,) unicode: channel names
``group<i>_missing``   (T,) bool, optional
``extras``             (E,) unicode: extra names
``extra<j>``           (T, ...) float
=====================  ===========================================================

``.csv``: one header line of column names, then one row per sample, ``.``
as decimal separator, ``,`` as delimiter:

* ``t`` first;
* ``<group>.<channel>`` per channel, e.g. ``orientation.qw``, ``emg.emg0``,
  ``robot.left_s0``, ``/left_hand_1.x`` (the group is everything before the
  last ``.``; groups appear in column order);
* ``<group>.missing`` (0/1), optional: 1 marks a missing sample (its values
  may be empty or ``nan``);
* ``extras:<name>.<k>`` for column k of an extra, e.g. ``extras:endpoint_pose.0``.

Lines starting with ``#`` are comments. Example::

    t,orientation.qw,orientation.qx,orientation.qy,orientation.qz,emg.emg0,...,robot.left_s0,...
    0.0,0.95,0.1,0.2,0.2,31.0,...,-0.84,...
"""

from __future__ import annotations

import csv
import io
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import GRIPPER, GRIPPER_CHANNELS, ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..inputs import check_regular
from ..signals.checks import GRIPPER_HINT, pose_like
from ..signals.gripper import gripper_values
from ..signals.groups import group_spec
from ..signals.preprocess import Stream, align_streams
from .streams import full_duration_s

FORMAT_TAG = "ipromp_pin.demo"
VERSION = 1
UNIFORM_TOLERANCE = 0.01
"""Maximum relative deviation of a native demo's sample spacing from its median."""
SUFFIXES = (".npz", ".csv")


def is_native_folder(folder: Path) -> bool:
    """Whether ``folder`` holds native demo files (``*.npz``, or ``*.csv`` whose first column is ``t``)."""
    folder = Path(folder)
    if any(folder.glob("*.npz")):
        return True
    for p in folder.glob("*.csv"):
        try:
            with open(p, newline="") as fh:
                for line in fh:
                    if not line.startswith("#"):
                        return line.split(",")[0].strip() == "t"
        except (OSError, UnicodeDecodeError):
            continue
    return False


def list_demos(folder: Path, order: str = "config") -> list[Path]:
    """Demo files of a task folder, by file name.

    Raises:
        DataError: a demo exists both as ``.npz`` and ``.csv``.
    """
    if order not in ("config", "recorded"):
        raise DataError(folder, "order", f"unknown demo order {order!r} (use 'config' or 'recorded')")
    files = sorted(p for p in Path(folder).iterdir() if p.suffix in SUFFIXES and p.is_file())
    stems: dict[str, Path] = {}
    for p in files:
        if p.stem in stems:
            raise DataError(p, None, f"demo {p.stem!r} exists as both {stems[p.stem].name} and {p.name}")
        stems[p.stem] = p
    return files


# ------------------------------------------------------------------------------------------ writing
def write_demo(demo: Demo, path: str | Path) -> Path:
    """Write a demo as ``.npz`` or ``.csv`` (by the suffix of ``path``), atomically; returns the path."""
    path = Path(path)
    if path.suffix == ".npz":
        arrays: dict[str, np.ndarray] = {
            "format": np.array(FORMAT_TAG),
            "version": np.array(VERSION),
            "task": np.array(demo.task),
            "name": np.array(demo.name),
            "duration_s": np.array(full_duration_s(demo)),
            "t": demo.t,
            "groups": np.array(list(demo.groups), dtype=str),
            "extras": np.array(list(demo.extras), dtype=str),
        }
        for i, (g, v) in enumerate(demo.groups.items()):
            arrays[f"group{i}"] = v
            arrays[f"group{i}_channels"] = np.array(demo.channel_names[g], dtype=str)
            if g in demo.missing:
                arrays[f"group{i}_missing"] = np.asarray(demo.missing[g], dtype=bool)
        for j, v in enumerate(demo.extras.values()):
            arrays[f"extra{j}"] = np.asarray(v, dtype=float)
        with atomic.replacing(path) as tmp, open(tmp, "wb") as fh:
            # allow_pickle: numpy's default, named so that the arrays fill only its **kwds.
            np.savez_compressed(fh, allow_pickle=True, **arrays)
        return path
    if path.suffix == ".csv":
        header = ["t"]
        cols = [demo.t[:, None]]
        for g, v in demo.groups.items():
            header += [f"{g}.{c}" for c in demo.channel_names[g]]
            cols.append(v)
            if g in demo.missing:
                header.append(f"{g}.missing")
                cols.append(np.asarray(demo.missing[g], dtype=float)[:, None])
        for name, v in demo.extras.items():
            v = np.asarray(v, dtype=float).reshape(demo.n_samples, -1)
            header += [f"extras:{name}.{k}" for k in range(v.shape[1])]
            cols.append(v)
        data = np.hstack(cols)
        with atomic.replacing(path) as tmp, open(tmp, "w", newline="") as fh:
            fh.write(",".join(header) + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.12g")
        return path
    raise DataError(path, None, "native demos are .npz or .csv files")


def write_dataset(dataset: Dataset, folder: str | Path, suffix: str = ".npz") -> list[Path]:
    """Write every demo of a dataset as ``<folder>/<task>/<name><suffix>``."""
    folder = Path(folder)
    return [
        write_demo(d, folder / task / f"{d.name.replace('/', '_')}{suffix}")
        for task, demos in dataset.demos.items()
        for d in demos
    ]


# ------------------------------------------------------------------------------------------ reading
def _check_time(path: Path, t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DataError(path, "t", f"must be 1-D, got shape {t.shape}")
    if t.size < 2:
        raise DataError(path, "t", f"a demo needs at least 2 samples, got {t.size}")
    if not np.all(np.isfinite(t)):
        raise DataError(path, "t", "contains NaN or inf")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise DataError(path, "t", f"not strictly increasing at sample {k + 1} (t={t[k + 1]})")
    med = float(np.median(dt))
    if np.max(np.abs(dt - med)) > UNIFORM_TOLERANCE * med:
        raise DataError(path, "t", f"not uniformly spaced (median step {med:g} s; resample the demo first)")
    return t - t[0]


MAX_DEMO_BYTES = 500_000_000
"""Largest native demo file in [bytes] (an hour at 50 Hz of 40 channels is about 60 MB as CSV)."""

MAX_EXPANSION = 50.0
"""Largest ratio of a ``.npz`` member's size to its compressed size (plus 1 MB): numeric demo data
compress a few-fold; a member that expands a thousandfold is not a demo (and would exhaust memory)."""


def _npz_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a ``.npz`` demo file, after checking that none expands implausibly."""
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if info.file_size > MAX_EXPANSION * info.compress_size + 1_000_000:
                    raise DataError(
                        path, info.filename, f"member expands to {info.file_size} bytes: not a demo file"
                    )
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except DataError:
        raise
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise DataError(path, None, f"corrupt or truncated .npz file ({exc})") from None


def _read_npz(path: Path, task: str | None) -> Demo:
    data = _npz_arrays(path)

    def get(key: str) -> np.ndarray:
        if key not in data:
            raise DataError(path, key, "missing array")
        return data[key]

    def text(key: str) -> str:
        v = get(key)
        if v.shape != () or v.dtype.kind != "U":
            raise DataError(path, key, f"must be a text scalar, got {v.dtype} of shape {v.shape}")
        return str(v[()])

    def names(key: str) -> list[str]:
        v = get(key)
        if v.ndim != 1 or v.dtype.kind != "U":
            raise DataError(path, key, f"must be a 1-D array of names, got {v.dtype} of shape {v.shape}")
        return [str(x) for x in v.tolist()]

    def numbers(key: str, kinds: str = "fiu") -> np.ndarray:
        v = get(key)
        if v.dtype.kind not in kinds:
            raise DataError(path, key, f"must hold numbers, holds {v.dtype}")
        return np.asarray(v, dtype=float)

    def scalar(key: str) -> float:
        v = numbers(key)
        if v.shape != ():
            raise DataError(path, key, f"must be a number, got shape {v.shape}")
        return float(v)

    fmt = text("format") if "format" in data else ""
    if fmt != FORMAT_TAG:
        raise DataError(path, "format", f"not an ipromp_pin demo file (format {fmt!r})")
    version = scalar("version")
    if version != int(version) or version < 1:
        raise DataError(path, "version", f"must be a positive integer, got {version}")
    if version > VERSION:
        raise DataError(
            path, "version", f"written by a newer ipromp_pin (version {int(version)} > {VERSION})"
        )
    t = _check_time(path, numbers("t"))
    groups, channels, missing = {}, {}, {}
    group_names = names("groups")
    if len(set(group_names)) != len(group_names):
        raise DataError(path, "groups", f"a group is listed twice in {group_names}")
    for i, g in enumerate(group_names):
        v = numbers(f"group{i}")
        if v.ndim != 2 or v.shape[0] != t.size:
            raise DataError(path, g, f"values of shape {v.shape} do not match {t.size} samples")
        groups[g] = v
        channels[g] = tuple(names(f"group{i}_channels"))
        if f"group{i}_missing" in data:
            missing[g] = numbers(f"group{i}_missing", "bfiu").astype(bool)
    extras = {n: numbers(f"extra{j}") for j, n in enumerate(names("extras"))}
    for n, v in extras.items():
        if v.shape[:1] != (t.size,):
            raise DataError(path, f"extras:{n}", f"shape {v.shape} does not match {t.size} samples")
    duration = scalar("duration_s") if "duration_s" in data else None
    if duration is not None and not (np.isfinite(duration) and duration >= t[-1] - 1e-9):
        raise DataError(path, "duration_s", f"{duration} is shorter than the demo's {t[-1]:.3f} s")
    return Demo(
        task=task if task is not None else path.parent.name,
        name=path.stem,
        source=str(path),
        t=t,
        groups=groups,
        channel_names=channels,
        missing=missing,
        extras=extras,
        duration_s=duration,
    )


def _read_csv(path: Path, task: str | None) -> Demo:
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (spreadsheet exports) is dropped
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(path, None, f"cannot read: {exc}") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not lines:
        raise DataError(path, None, "empty file (no header line)")
    rows = list(csv.reader(io.StringIO("\n".join(lines))))
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    if not header or header[0] != "t":
        raise DataError(path, "t", "the first column must be 't'")
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(path, dup, "column appears twice")
    for k, r in enumerate(body):
        if len(r) != len(header):
            raise DataError(
                path, f"line {k + 2}", f"has {len(r)} fields, the header has {len(header)} (truncated?)"
            )
    if len(body) < 2:
        raise DataError(path, None, f"a demo needs at least 2 samples, got {len(body)}")
    try:
        data = np.array([[float(x) if x.strip() else np.nan for x in r] for r in body])
    except ValueError:
        for k, r in enumerate(body):
            for h, x in zip(header, r, strict=True):
                try:
                    float(x) if x.strip() else None
                except ValueError:
                    raise DataError(path, h, f"line {k + 2}: not a number: {x!r}") from None
        raise
    t = _check_time(path, data[:, 0])
    groups: dict[str, list[tuple[str, int]]] = {}
    missing_col: dict[str, int] = {}
    extras: dict[str, list[tuple[str, int]]] = {}
    for j, h in enumerate(header[1:], start=1):
        if h.startswith("extras:"):
            name, _, part = h[len("extras:") :].rpartition(".")
            extras.setdefault(name or part, []).append((part if name else "", j))
            continue
        if "." not in h:
            raise DataError(path, h, "column name is not '<group>.<channel>'")
        g, c = h.rsplit(".", 1)
        if c == "missing":
            missing_col[g] = j
        else:
            groups.setdefault(g, []).append((c, j))
    if not groups:
        raise DataError(path, None, "no channel columns")
    values, names, missing = {}, {}, {}
    for g, chans in groups.items():
        values[g] = data[:, [j for _, j in chans]]
        names[g] = tuple(c for c, _ in chans)
        if g in missing_col:
            m = data[:, missing_col[g]]
            if not np.all(np.isin(m, (0.0, 1.0))):
                raise DataError(path, f"{g}.missing", "must be 0 or 1")
            missing[g] = m.astype(bool)
    for g in missing_col:
        if g not in groups:
            raise DataError(path, f"{g}.missing", "missing-sample column of a group without channels")
    ex = {name: data[:, extra_columns(path, name, parts)] for name, parts in extras.items()}
    return Demo(
        task=task if task is not None else path.parent.name,
        name=path.stem,
        source=str(path),
        t=t,
        groups=values,
        channel_names=names,
        missing=missing,
        extras=ex,
    )


def extra_columns(path: Path, name: str, parts: list[tuple[str, int]]) -> list[int]:
    """The columns of extra ``name`` in the order their names say (``extras:<name>.<part>``): parts
    ``0, 1, 2, ...`` by number, ``x, y, z`` (and ``w``) as a vector, else as they come. Columns in
    another order in the file (``.2, .0, .1``) are read by name, never by position."""
    names = [p for p, _ in parts]
    if all(p.isdigit() for p in names):
        numbers = sorted(int(p) for p in names)
        if numbers != list(range(len(names))):
            raise DataError(
                path, f"extras:{name}", f"columns are numbered {names}, not 0 to {len(names) - 1}"
            )
        return [j for _, j in sorted(parts, key=lambda pj: int(pj[0]))]
    for axes in ("xyz", "xyzw"):
        if sorted(names) == sorted(axes):
            return [dict(parts)[a] for a in axes]
    return [j for _, j in parts]


def _select_joints(demo: Demo, joints: tuple[str, ...]) -> Demo:
    have = demo.channel_names[ROBOT]
    posed = pose_like(joints)
    if posed:  # robot_joints=("x", "y", "z") would label a position as joint angles in [rad]
        raise DataError(
            demo.source,
            "robot_joints",
            f"{', '.join(posed)} are a pose's channels, not joints: " + GRIPPER_HINT,
        )
    if pose_like(have):
        raise DataError(
            demo.source,
            ROBOT,
            f"the robot group holds {', '.join(have)}, a pose, not joint angles in [rad]: {GRIPPER_HINT}",
        )
    if have == joints:
        return demo
    for j in joints:
        if j not in have:
            raise DataError(demo.source, j, f"unknown joint name (the robot group has: {', '.join(have)})")
    idx = [have.index(j) for j in joints]
    groups = dict(demo.groups)
    groups[ROBOT] = demo.groups[ROBOT][:, idx]
    return Demo(
        task=demo.task,
        name=demo.name,
        source=demo.source,
        t=demo.t,
        groups=groups,
        channel_names={**demo.channel_names, ROBOT: joints},
        missing=dict(demo.missing),
        extras=dict(demo.extras),
        duration_s=demo.duration_s,
    )


def canonical_gripper(demo: Demo) -> Demo:
    """``demo`` with its gripper group (if any) checked, in the canonical channel order
    (:data:`~ipromp_pin.data.GRIPPER_CHANNELS`) and its quaternion sign-continuous
    (:func:`~ipromp_pin.signals.gripper.gripper_values`); DataError naming the file and field."""
    if GRIPPER not in demo.groups:
        return demo
    if GRIPPER in demo.missing and np.any(demo.missing[GRIPPER]):
        raise DataError(demo.source, GRIPPER, "a gripper pose path has no missing samples (fill or cut them)")
    values = gripper_values(demo.source, GRIPPER, demo.groups[GRIPPER], demo.channel_names[GRIPPER])
    return Demo(
        task=demo.task,
        name=demo.name,
        source=demo.source,
        t=demo.t,
        groups={**demo.groups, GRIPPER: values},
        channel_names={**demo.channel_names, GRIPPER: GRIPPER_CHANNELS},
        missing={g: m for g, m in demo.missing.items() if g != GRIPPER},
        extras=dict(demo.extras),
        duration_s=demo.duration_s,
    )


def resample_demo(demo: Demo, rate_hz: float) -> Demo:
    """The demo on a uniform grid at ``rate_hz`` (each group by the interpolation of its channel-group
    specification: linear, ``"orientation"`` as quaternions; extras linear; a grid sample next to a
    missing one is missing)."""
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(demo.source, "rate_hz", f"must be positive, got {rate_hz}")
    if abs(demo.dt * rate_hz - 1.0) < 1e-6:
        return demo
    streams = {}
    for g, v in demo.groups.items():
        kind = group_spec(g).interpolation_kind(v.shape[1])
        streams[g] = Stream(
            demo.t, v, demo.channel_names[g], kind, demo.source, allow_missing=g in demo.missing
        )
    for name, v in demo.extras.items():
        v = np.asarray(v, dtype=float).reshape(demo.n_samples, -1)
        streams["extras:" + name] = Stream(
            demo.t, v, tuple(str(k) for k in range(v.shape[1])), "linear", demo.source, allow_missing=True
        )
    t, values, _ = align_streams(streams, rate_hz, demo.source)
    missing = {}
    for g in demo.missing:
        m = ~np.all(np.isfinite(values[g]), axis=1)
        values[g][m] = np.nan
        missing[g] = m
    return Demo(
        task=demo.task,
        name=demo.name,
        source=demo.source,
        t=t,
        groups={g: values[g] for g in demo.groups},
        channel_names=dict(demo.channel_names),
        missing=missing,
        extras={
            n: values["extras:" + n].reshape((t.size,) + np.shape(demo.extras[n])[1:]) for n in demo.extras
        },
        duration_s=max(full_duration_s(demo), float(t[-1])),
    )


def read_demo(
    path: str | Path,
    task: str | None = None,
    *,
    rate_hz: float | None = None,
    frames: Sequence[str] | None = None,
    robot_joints: Sequence[str] | None = None,
) -> Demo:
    """Read one native demo (``.npz`` or ``.csv``).

    Args:
        path: The demo file.
        task: Task name (default: the folder's name).
        rate_hz: Resample onto this rate in [Hz] when the file's differs (default: keep it).
        frames: Groups that must be present (e.g. skeleton frames); DataError otherwise.
        robot_joints: Joints of the ``"robot"`` group to keep, in this order, by name
            (default: as stored). DataError naming a joint the file lacks.
    """
    path = Path(path)
    try:
        check_regular(path, "demo", lambda problem: DataError(path, None, problem), MAX_DEMO_BYTES)
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except OSError as exc:
        raise DataError(path, None, f"cannot read: {exc.strerror or exc}") from None
    if path.suffix == ".npz":
        demo = _read_npz(path, task)
    elif path.suffix == ".csv":
        demo = _read_csv(path, task)
    else:
        raise DataError(path, None, "native demos are .npz or .csv files")
    if frames:
        demo.require(frames)
    demo = canonical_gripper(demo)
    if robot_joints is not None and ROBOT in demo.groups:
        demo = _select_joints(demo, tuple(robot_joints))
    return demo if rate_hz is None else resample_demo(demo, rate_hz)
