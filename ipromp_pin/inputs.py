"""Reading a user's input file with bounds: a regular file of bounded size, a document of bounded
nesting.

:func:`read_bounded` refuses, before reading, what is not a regular file (a FIFO would block for
ever, ``/dev/zero`` would be read without end, a folder is not a document) and a file above its
size bound, and never reads more than the bound even if the file grows meanwhile.
:func:`load_toml` parses a TOML document so read and turns the parser's ``RecursionError`` (a
document nested thousands of levels deep) into the caller's one-line error.
"""

from __future__ import annotations

import os
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path

MAX_DOCUMENT_BYTES = 1_000_000
"""Largest settings, pipeline or limit-profile file in [bytes] (the shipped ones are under 10 kB)."""

ErrorFn = Callable[[str], Exception]
"""Builds the caller's one-line error from a problem (the caller adds its file and field)."""


def _kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a named pipe (FIFO)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def check_regular(path: Path, what: str, error: ErrorFn, max_bytes: int) -> int:
    """The size in [bytes] of ``path``, a regular file of at most ``max_bytes``; else ``error``.

    Raises:
        FileNotFoundError: ``path`` does not exist (callers name the missing file their own way).
    """
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise error(f"is {_kind(st.st_mode)}, not a {what} file")
    if st.st_size > max_bytes:
        raise error(f"{st.st_size} bytes is too large for a {what} file (at most {max_bytes})")
    return st.st_size


def read_bounded(path: str | Path, what: str, error: ErrorFn, max_bytes: int = MAX_DOCUMENT_BYTES) -> bytes:
    """The content of ``path`` (:func:`check_regular` first; at most ``max_bytes`` are read)."""
    path = Path(path)
    check_regular(path, what, error, max_bytes)
    with open(path, "rb") as fh:
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise error(f"grew beyond {max_bytes} bytes while being read; not a {what} file")
    return data


def load_toml(path: str | Path, what: str, error: ErrorFn, max_bytes: int = MAX_DOCUMENT_BYTES) -> dict:
    """The TOML document of ``path`` (:func:`read_bounded`; UTF-8, a byte-order mark dropped).

    Raises:
        The caller's ``error`` for a file that is not regular or too large, not UTF-8, not TOML or
        nested too deeply; ``FileNotFoundError`` and other ``OSError`` as they come.
    """
    data = read_bounded(path, what, error, max_bytes)
    try:
        return tomllib.loads(data.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise error(f"not a valid TOML {what} file (not valid TOML: not UTF-8 text, {exc.reason})") from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"not a valid TOML {what} file: {exc}") from None
    except RecursionError:
        raise error(f"not a usable {what} file: nested too deeply") from None
