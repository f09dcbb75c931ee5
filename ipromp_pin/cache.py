"""Where ipromp_pin keeps what it computes once and reuses across runs (the decimated preview meshes).

The folder is ``$IPROMP_PIN_CACHE_DIR`` when set, else the user's cache folder:
``$XDG_CACHE_HOME/ipromp_pin`` or ``~/.cache/ipromp_pin`` (Linux and other POSIX systems),
``~/Library/Caches/ipromp_pin`` (macOS), ``%LOCALAPPDATA%\\ipromp_pin\\Cache`` (Windows). Everything in
it can be deleted at any time: it is rebuilt on demand. Readers of a cache must treat a missing,
unreadable or corrupt entry as absent, and writers a read-only folder as "do not cache"
(:func:`write_atomically` does).
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["CACHE_ENV", "cache_dir", "write_atomically"]

CACHE_ENV = "IPROMP_PIN_CACHE_DIR"
"""Environment variable naming the cache folder (overrides the user's cache folder)."""


def cache_dir(kind: str = "") -> Path:
    """The cache folder (not created), or its sub-folder ``kind``."""
    override = os.environ.get(CACHE_ENV)
    if override:
        root = Path(override).expanduser()
    elif sys.platform == "win32":
        local = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
        root = local / "ipromp_pin" / "Cache"
    elif sys.platform == "darwin":
        root = Path.home() / "Library" / "Caches" / "ipromp_pin"
    else:
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "ipromp_pin"
    return root / kind if kind else root


def write_atomically(path: Path, write: Callable[[Path], None]) -> bool:
    """Write ``path`` through ``write(temporary_path)`` and rename it into place (readers never see a
    partial file). Returns False, leaving nothing behind, when the folder cannot be created or
    written (read-only, full disk): a cache that cannot be written is simply not used."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
        os.close(fd)
        tmp = Path(name)
        write(tmp)
        os.replace(tmp, path)
        return True
    except OSError:
        if tmp is not None:
            try:
                tmp.unlink()
            except OSError:
                pass
        return False
