"""Folders of the settings files shipped with the package: robot settings and pipeline definitions.

The project keeps them in its top-level folders ``robots/`` and ``pipelines/``, their single
source. A wheel carries the same files inside the package, as ``ipromp_pin/robots`` and
``ipromp_pin/pipelines`` (``[tool.setuptools.package-dir]`` in ``pyproject.toml``); a source
checkout, run in place or installed in editable mode, has them beside the package.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


def shipped_dir(name: str) -> Path:
    """Folder ``name`` of shipped files: inside the installed package (wheel), else beside it (checkout)."""
    inside = _PACKAGE_DIR / name
    return inside if inside.is_dir() else _PACKAGE_DIR.parent / name


ROBOTS_DIR = shipped_dir("robots")
"""Folder of the shipped robot settings files (``robots/*.toml``)."""

PIPELINES_DIR = shipped_dir("pipelines")
"""Folder of the shipped pipeline definitions (``pipelines/*.toml``)."""

DEFAULT_ROBOT = "baxter_left"
"""The robot settings used when none is named: a shipped settings file (``robots/baxter_left.toml``)."""
