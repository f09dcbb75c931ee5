"""Atomic output files: nothing half-written, no earlier file destroyed by a failed run.

Every output is written to a temporary file (or folder) in its destination folder and renamed
into place once complete (``os.replace``: a reader sees the old file or the new one, never a
mixture or a truncated file). A run that writes several files stages them all in an
:class:`OutputSet` and commits them together: either every file of the run is in place, or the
previous files are untouched (a failed commit restores them).

Single files::

    atomic.write_text(path, text)
    atomic.write_bytes(path, data)
    with atomic.replacing(path) as tmp:      # any writer that takes a path (np.savez, savefig, ...)
        write_something(tmp)

A set of files (and folders)::

    with atomic.OutputSet(out_dir, managed=("trajectory.csv", "report.json", "preview.html")) as out:
        out.write_text("report.json", text)
        plot_to(out.stage("figure.png"))       # a temporary path in out_dir; write to it
        bag = out.stage_dir("trajectory_bag")  # a temporary folder (e.g. a rosbag2 folder)
        out.commit()                           # rename everything into place

``managed`` names the files a run of this kind may write: those of an earlier run that this run
does not write are removed at the commit, so the folder never mixes two runs' files. Without
``commit`` (an exception in the block) every staged file is deleted and nothing changes.

Temporary names are hidden and keep the final suffix (``.trajectory.k3x9.partial.csv``), so
writers that infer the format from the suffix work. Missing parent folders are created. Every
failure raises :class:`~ipromp_pin.exceptions.OutputError` naming the path and the problem;
:func:`check_output_file` and :func:`check_output_dir` find most of them before any computation.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

from .exceptions import OutputError

__all__ = [
    "OutputSet",
    "check_output_dir",
    "check_output_file",
    "replacing",
    "write_bytes",
    "write_text",
]


def _problem(exc: OSError) -> str:
    return exc.strerror or str(exc) or type(exc).__name__


def _existing_ancestor(path: Path) -> Path:
    p = path.parent
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _check_writable_parent(path: Path, what: str) -> None:
    ancestor = _existing_ancestor(path)
    if not ancestor.is_dir():
        raise OutputError(f"{path}: cannot write the {what}: {ancestor} is a file, not a folder")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write the {what}: folder {ancestor} is not writable")


def check_output_file(path: str | Path, what: str = "output file") -> Path:
    """Check, before any computation, that ``path`` can be written as a file.

    Raises:
        OutputError: ``path`` is a folder, a parent is a file, or the folder that would hold it
            (its nearest existing ancestor) is not writable.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: cannot write the {what}: it is a folder")
    if path.exists() and not os.access(path, os.W_OK) and not os.access(path.parent, os.W_OK):
        raise OutputError(f"{path}: cannot write the {what}: the file and its folder are read-only")
    _check_writable_parent(path, what)
    return path


def check_output_dir(path: str | Path, what: str = "output folder") -> Path:
    """Check, before any computation, that ``path`` is or can become a writable folder.

    Raises:
        OutputError: ``path`` is a file, a parent is a file, or ``path`` (or its nearest existing
            ancestor) is not writable.
    """
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise OutputError(f"{path}: cannot use it as the {what}: it is a file")
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: the {what} is not writable")
        return path
    _check_writable_parent(path, what)
    return path


def _make_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"{folder}: cannot create the folder: a file of that name exists") from None
    except OSError as exc:
        raise OutputError(f"{folder}: cannot create the folder: {_problem(exc)}") from None


_UMASK: list[int] = []


def _default_mode() -> int:
    """Permissions of a newly created file (0666 minus the process umask)."""
    if not _UMASK:
        mask = os.umask(0o022)
        os.umask(mask)
        _UMASK.append(mask)
    return 0o666 & ~_UMASK[0]


def _temp_name(final: Path, token: str) -> str:
    return f".{final.stem}.{token}.partial{final.suffix}"


def _new_temp(final: Path, directory: bool = False) -> Path:
    """Create (exclusively) an empty temporary file or folder beside ``final``."""
    for _ in range(100):
        tmp = final.with_name(_temp_name(final, secrets.token_hex(4)))
        try:
            if directory:
                tmp.mkdir()
            else:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                os.close(fd)
            return tmp
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"{final}: cannot write: {_problem(exc)}") from None
    raise OutputError(f"{final}: cannot create a temporary file beside it")  # pragma: no cover


def _finish_file(tmp: Path, final: Path) -> None:
    """Give ``tmp`` the permissions ``final`` has (or a new file gets) and flush it to disk."""
    try:
        mode = stat.S_IMODE(final.stat().st_mode) if final.is_file() else _default_mode()
    except OSError:
        mode = _default_mode()
    try:
        os.chmod(tmp, mode)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
    except OSError as exc:
        raise OutputError(f"{final}: cannot write: {_problem(exc)}") from None


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


@contextlib.contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Context manager yielding a temporary path beside ``path``; on a normal exit the file written
    there replaces ``path`` atomically, on an exception it is deleted and ``path`` is untouched.

    Raises:
        OutputError: the folder cannot be created or written, or the rename fails.
    """
    final = Path(path)
    if final.is_dir():
        raise OutputError(f"{final}: cannot write the file: it is a folder")
    _make_folder(final.parent)
    tmp = _new_temp(final)
    try:
        try:
            yield tmp
        except OSError as exc:
            raise OutputError(f"{final}: cannot write: {_problem(exc)}") from None
        _finish_file(tmp, final)
        try:
            os.replace(tmp, final)
        except OSError as exc:
            raise OutputError(f"{final}: cannot replace the file: {_problem(exc)}") from None
        _fsync_dir(final.parent)
    finally:
        if tmp.exists():
            _remove(tmp)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    with replacing(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (``\\n`` line ends kept as they are); returns the path."""
    return write_bytes(path, text.encode(encoding))


class OutputSet:
    """Files (and folders) of one run, staged in their folder and renamed into place together.

    Args:
        folder: The output folder (created, with its parents, when missing).
        managed: Names of every file or folder a run of this kind may write; those present from
            an earlier run but not written by this one are removed at :meth:`commit`.

    Attributes:
        folder: The output folder.
        files: Name -> final path of everything staged so far, in staging order.
    """

    def __init__(self, folder: str | Path, *, managed: Iterable[str] = ()) -> None:
        self.folder = Path(folder)
        self.managed = tuple(managed)
        for name in self.managed:
            self._check_name(name)
        self._staged: dict[str, tuple[Path, bool]] = {}  # name -> (temp path, is a folder)
        self._done = False
        check_output_dir(self.folder)
        _make_folder(self.folder)

    @staticmethod
    def _check_name(name: str) -> None:
        if not name or name in (".", "..") or "/" in name or os.sep in name:
            raise ValueError(f"output name {name!r} must be a plain file name")

    @property
    def files(self) -> dict[str, Path]:
        """Name -> final path of everything staged."""
        return {name: self.folder / name for name in self._staged}

    def path(self, name: str) -> Path:
        """The final path of ``name`` (where it will be after :meth:`commit`)."""
        return self.folder / name

    def _stage(self, name: str, directory: bool) -> Path:
        if self._done:
            raise ValueError("this output set was already committed or discarded")
        self._check_name(name)
        if name in self._staged:
            raise ValueError(f"output {name!r} staged twice")
        final = self.folder / name
        tmp = _new_temp(final, directory=directory)
        self._staged[name] = (tmp, directory)
        return tmp

    def stage(self, name: str) -> Path:
        """A temporary file path for ``name`` in the output folder: write the content there."""
        return self._stage(name, directory=False)

    def stage_dir(self, name: str) -> Path:
        """A temporary (empty) folder for ``name`` in the output folder: fill it."""
        return self._stage(name, directory=True)

    def write_bytes(self, name: str, data: bytes) -> Path:
        """Stage ``name`` with ``data``; returns its final path."""
        tmp = self.stage(name)
        try:
            tmp.write_bytes(data)
        except OSError as exc:
            raise OutputError(f"{self.folder / name}: cannot write: {_problem(exc)}") from None
        return self.folder / name

    def write_text(self, name: str, text: str, encoding: str = "utf-8") -> Path:
        """Stage ``name`` with ``text``; returns its final path."""
        return self.write_bytes(name, text.encode(encoding))

    def commit(self) -> dict[str, Path]:
        """Rename every staged file into place and remove the managed files this run did not write.

        Each name is replaced atomically (a reader sees the old file or the new one). If a rename
        fails, the files already replaced are restored from their backups and the error is
        raised: the folder then holds the previous run's files, unchanged.

        Returns:
            Name -> final path of the committed files, in staging order.

        Raises:
            OutputError: a staged file is missing or a rename failed (nothing changed).
        """
        if self._done:
            raise ValueError("this output set was already committed or discarded")
        token = secrets.token_hex(4)
        backups: list[tuple[Path, Path]] = []  # (final, backup)
        placed: list[Path] = []  # finals that now hold new content and had no earlier file
        try:
            for name, (tmp, directory) in self._staged.items():
                final = self.folder / name
                if not tmp.exists():
                    raise OutputError(f"{final}: nothing was written to the staged file")
                if not directory:
                    _finish_file(tmp, final)
                backup = final.with_name(f".{final.name}.{token}.previous")
                if final.exists() or final.is_symlink():
                    if directory or final.is_dir():
                        os.replace(final, backup)  # folders: moved aside, then replaced
                    else:
                        _keep_copy(final, backup)
                    backups.append((final, backup))
                else:
                    placed.append(final)
                os.replace(tmp, final)
            for name in self.managed:
                final = self.folder / name
                if name in self._staged or not (final.exists() or final.is_symlink()):
                    continue
                backup = final.with_name(f".{final.name}.{token}.previous")
                os.replace(final, backup)
                backups.append((final, backup))
        except BaseException as exc:  # also an interruption (Ctrl-C, SIGTERM) in the middle of the renames
            for final in placed:
                _remove(final)
            for final, backup in reversed(backups):
                with contextlib.suppress(OSError):
                    if final.exists() and os.path.samefile(final, backup):
                        backup.unlink()  # a hard link to the file, which was not replaced
                        continue
                    if final.is_dir() and not final.is_symlink():
                        shutil.rmtree(final)
                    os.replace(backup, final)
            self.discard()
            if isinstance(exc, OutputError) or not isinstance(exc, OSError):
                raise
            where = getattr(exc, "filename", None) or self.folder
            raise OutputError(f"{where}: cannot write the outputs: {_problem(exc)}") from None
        for _, backup in backups:
            _remove(backup)
        _fsync_dir(self.folder)
        self._done = True
        return self.files

    def discard(self) -> None:
        """Delete every staged file; the output folder keeps its previous content."""
        for tmp, _ in self._staged.values():
            _remove(tmp)
        self._done = True

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if not self._done:
            self.discard()


def _keep_copy(final: Path, backup: Path) -> None:
    """Keep the current content of ``final`` at ``backup`` without removing ``final`` (a hard
    link, or a copy where links are not supported)."""
    try:
        os.link(final, backup)
    except OSError:
        shutil.copy2(final, backup)
