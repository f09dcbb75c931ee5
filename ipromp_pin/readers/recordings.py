"""Single recordings: the format of one recording's path, and the recordings that paths hold.

A recording is one demonstration, in any format the readers read, without a task label:

* ``"multimodal"``: a ``multiModal_states.csv``, or a folder holding one;
* ``"bag"``: a ROS 1 ``.bag`` file;
* ``"rosbag2"``: a rosbag2 folder (``metadata.yaml`` with ``.mcap`` or ``.db3`` files), or one
  ``.mcap`` / ``.db3`` file;
* ``"native"``: a ``.npz`` demo file, or a ``.csv`` one (first column ``t``);
* ``"chen2017"``: one stamp of the per-topic CSV export: any of its files
  ``<stamp>-<topic>.csv`` or their common prefix ``<folder>/<stamp>`` (the files may lie in any
  folder).

:func:`expand_recordings` turns files and folders into recordings: a file is one recording; a folder
is one recording (a rosbag2 folder, a folder holding ``multiModal_states.csv``) or holds several,
of one format, directly or in its ``csv/`` sub-folder (a task folder of a dataset), or in
sub-folders (a dataset: every non-hidden sub-folder whose name does not start with ``_`` must hold
recordings). A chen2017 task folder holds the CSV export and the original bags of the same demos:
the CSV export is read (as ``load_dataset`` does); any other mix of formats in one folder is an
error, since the same demo may be there twice.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from ..exceptions import DataError
from . import chen2017, multimodal, rosbag2

UNKNOWN_TASK = ""
"""``Demo.task`` of a recording read without a task label (:func:`ipromp_pin.readers.read_recording`)."""

MAX_DEPTH = 4
"""Folder levels :func:`expand_recordings` descends below a folder it is given."""

FORMAT_ORDER = ("chen2017", "multimodal", "native", "bag", "rosbag2")
"""The formats of one folder, in the order they are listed in error messages."""

_CHEN2017_SUFFIXES = tuple(f"-{s}.csv" for s in chen2017.TOPIC_SUFFIXES.values())
_EXPECTED = (
    "a multiModal_states.csv, a .bag, a rosbag2 folder or .mcap/.db3 file, a native .npz/.csv demo, or a "
    "chen2017 export's <stamp>-<topic>.csv files"
)


def _chen2017_prefix(path: Path) -> Path | None:
    """``<folder>/<stamp>`` when ``path`` is a chen2017 export file or prefix, else None."""
    m = chen2017.STAMP_RE.match(path.name)
    if not m:
        return None
    stamp = m.group(1)
    if path.name[len(stamp) :] in _CHEN2017_SUFFIXES:
        return path.parent / stamp
    if path.name == stamp:
        emg = path.parent / f"{stamp}-{chen2017.TOPIC_SUFFIXES['emg']}.csv"
        if emg.is_file() or path.parent.name == "csv":
            return path
    return None


def _is_native_csv(path: Path) -> bool:
    """Whether the first line (after ``#`` comments) of a CSV file starts with the column ``t``."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            for line in fh:
                if not line.startswith("#"):
                    return line.split(",")[0].strip() == "t"
    except (OSError, UnicodeDecodeError):
        return False
    return False


def recording_format(path: str | Path) -> str:
    """The format of the one recording at ``path`` (see the module docstring).

    Raises:
        DataError: nothing there, or not a recording (a folder of several: :func:`expand_recordings`).
    """
    path = Path(path)
    prefix = _chen2017_prefix(path)
    if prefix is not None and (path.is_file() or not path.exists()):
        return "chen2017"
    if not path.exists():
        raise DataError(path, None, "file or folder not found")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "rosbag2"
        if (path / multimodal.FILE_NAME).is_file():
            return "multimodal"
        raise DataError(path, None, f"a folder, not one recording (expected {_EXPECTED})")
    if path.name == multimodal.FILE_NAME:
        return "multimodal"
    suffix = path.suffix.lower()
    if suffix == ".bag":
        return "bag"
    if suffix in rosbag2.STORAGE_SUFFIXES:
        return "rosbag2"
    if suffix in (".npz", ".csv"):
        return "native"
    raise DataError(path, "format", f"not a recording (expected {_EXPECTED})")


def _canonical(path: Path, fmt: str) -> Path:
    """The path that names a recording once (a chen2017 stamp's prefix, a rosbag2 folder ...)."""
    if fmt == "chen2017":
        prefix = _chen2017_prefix(path)
        return path if prefix is None else prefix
    if fmt == "rosbag2":
        return rosbag2.recording_path(path)
    if fmt == "multimodal" and path.is_dir():
        return path / multimodal.FILE_NAME
    return path


def recording_name(path: str | Path) -> str:
    """The name the readers give the recording at ``path`` (a path :func:`expand_recordings` returns):
    a multimodal recording's folder name, a chen2017 stamp, a rosbag2 folder's name, else the file's
    name without its suffix."""
    path = Path(path)
    fmt = recording_format(path)
    if fmt == "multimodal":
        return (path if path.is_dir() else path.parent).name
    if fmt == "chen2017" or (fmt == "rosbag2" and path.is_dir()):
        return path.name
    return path.stem


def _visible(folder: Path) -> list[Path]:
    try:
        return sorted(p for p in folder.iterdir() if not p.name.startswith("."))
    except OSError as exc:
        raise DataError(folder, None, f"cannot read the folder: {exc.strerror or exc}") from None


def _found_in(folder: Path) -> dict[str, list[Path]]:
    """The recordings directly in ``folder`` (or its ``csv/`` sub-folder), by format."""
    entries = _visible(folder)
    csv_dir = folder / "csv"
    inner = _visible(csv_dir) if csv_dir.is_dir() else []
    found: dict[str, list[Path]] = {f: [] for f in FORMAT_ORDER}
    for p in entries + inner:
        if p.is_dir():
            if (p / "metadata.yaml").is_file():
                found["rosbag2"].append(p)
            elif (p / multimodal.FILE_NAME).is_file():
                found["multimodal"].append(p / multimodal.FILE_NAME)
            continue
        prefix = _chen2017_prefix(p)
        if prefix is not None:
            if p.name.endswith(f"-{chen2017.TOPIC_SUFFIXES['emg']}.csv"):
                found["chen2017"].append(prefix)
        elif p.name == multimodal.FILE_NAME:
            found["multimodal"].append(p)
        elif p.suffix == ".bag":
            found["bag"].append(p)
        elif p.suffix in rosbag2.STORAGE_SUFFIXES:
            found["rosbag2"].append(p)
        elif p.suffix == ".npz" or (p.suffix == ".csv" and _is_native_csv(p)):
            found["native"].append(p)
    return {f: v for f, v in found.items() if v}


def _folder_recordings(folder: Path, depth: int) -> list[Path]:
    """The recordings of a folder (itself, its files, or its sub-folders')."""
    if (folder / "metadata.yaml").is_file() or (folder / multimodal.FILE_NAME).is_file():
        return [_canonical(folder, recording_format(folder))]
    found = _found_in(folder)
    if "chen2017" in found and "bag" in found:
        stamps = {p.name for p in found["chen2017"]}
        if all(b.stem in stamps for b in found["bag"]):
            del found["bag"]  # the export's original bags: the same demos
    if len(found) > 1:
        counts = ", ".join(f"{len(v)} {f}" for f, v in found.items())
        raise DataError(
            folder,
            "format",
            f"holds recordings in several formats ({counts}): the same demo may be there twice; "
            "pass the recordings one by one, or keep one format per folder",
        )
    if found:
        return next(iter(found.values()))
    subfolders = [p for p in _visible(folder) if p.is_dir() and not p.name.startswith("_")]
    if not subfolders or depth >= MAX_DEPTH:
        raise DataError(folder, None, f"no recording found (expected {_EXPECTED})")
    out: list[Path] = []
    for sub in subfolders:
        try:
            out += _folder_recordings(sub, depth + 1)
        except DataError as exc:
            if exc.problem.startswith("no recording found"):
                raise DataError(
                    sub, None, "no recording found (rename the folder with a leading '_' to leave it out)"
                ) from None
            raise
    return out


def expand_recordings(paths: Iterable[str | Path]) -> list[Path]:
    """The recordings that files and folders hold, each once, in the order given (a folder's by name).

    Every returned path is one recording that :func:`recording_format` names and
    :func:`ipromp_pin.readers.read_recording` reads (a chen2017 stamp as its prefix
    ``<folder>/<stamp>``, a rosbag2 recording as its folder when it has one).

    Raises:
        DataError: a path that does not exist, a file that is not a recording, a folder without
            recordings (or with a sub-folder without any), a folder mixing formats.
    """
    out: dict[Path, None] = {}
    given = list(paths)
    if not given:
        raise DataError(None, "recordings", "no recording given")
    for p in given:
        path = Path(p)
        if path.is_dir():
            found = _folder_recordings(path, 0)
        else:
            found = [_canonical(path, recording_format(path))]
        for f in found:
            out.setdefault(f, None)
    return list(out)
