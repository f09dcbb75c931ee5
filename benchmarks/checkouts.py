"""Another checkout's package imported beside this one (for the paired comparisons of ``ab_compare.py``
and ``model_load.py``), and module look-ups that work across the package's layouts."""

from __future__ import annotations

import importlib
import shutil
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
OTHER = "ipromp_other"


def add_other(checkout: Path, tmp: Path, link: bool = False) -> None:
    """Make ``checkout``'s ``ipromp_pin`` importable as :data:`OTHER` from the folder ``tmp``, with this
    checkout's ``ipromp_pin`` importable too. ``link``: a symbolic link instead of a copy (for a
    checkout compared with itself: the same files, so numba's on-disk cache is shared, no compile)."""
    source = Path(checkout).resolve() / "ipromp_pin"
    if link:
        (tmp / OTHER).symlink_to(source, target_is_directory=True)
    else:
        shutil.copytree(source, tmp / OTHER, ignore=shutil.ignore_patterns("__pycache__"))
    sys.path[:0] = [str(tmp), str(ROOT)]


def first_module(package: str, *names: str) -> ModuleType:
    """The first of the modules ``package.<name>`` that exists (the layouts of successive commits:
    e.g. ``readers.synthetic`` today, ``synthetic`` before)."""
    for name in names:
        try:
            return importlib.import_module(f"{package}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name is None or not f"{package}.{name}".startswith(exc.name):
                raise
    raise ModuleNotFoundError(f"none of {', '.join(f'{package}.{n}' for n in names)}")
