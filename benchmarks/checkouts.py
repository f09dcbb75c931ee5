"""Another checkout's package imported beside this one (for the paired comparisons of ``ab_compare.py``
and ``model_load.py``), and module look-ups that work across the package's layouts."""

from __future__ import annotations

import importlib
import os
import shutil
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
OTHER = "ipromp_other"

# "this checkout" is the one this script belongs to, also where an installed ipromp_pin (an editable
# install of another checkout) would come first: imported before any module that imports ipromp_pin
if sys.path[:1] != [str(ROOT)]:
    sys.path.insert(0, str(ROOT))


def add_other(checkout: Path, tmp: Path) -> None:
    """Make a copy of ``checkout``'s ``ipromp_pin`` importable as :data:`OTHER` from the folder ``tmp``,
    with this checkout's ``ipromp_pin`` importable too. (A copy, never a link: numba's on-disk cache
    beside a linked package would get entries that name :data:`OTHER`, which this package's processes
    then fail to load.)"""
    source = Path(checkout).resolve() / "ipromp_pin"
    shutil.copytree(source, tmp / OTHER, ignore=shutil.ignore_patterns("__pycache__"))
    sys.path[:0] = [str(tmp), str(ROOT)]


def smoke_kernels(*packages: str) -> None:
    """For a smoke run: the numpy kernels in ``packages`` and numba's JIT off (set before numba is
    first imported), so that a fresh copy of a package compiles nothing."""
    os.environ["NUMBA_DISABLE_JIT"] = "1"
    for package in packages:
        first_module(package, "promp.compiled").set_kernel_backend("numpy")


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
