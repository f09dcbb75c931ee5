"""The robot's preview meshes: decimated once into the disk cache, in a forked process meanwhile.

:func:`start_mesh_prefetch` starts the decimation while a first run trains; :func:`preview_visual_model`
waits for it and returns the decimated visual model (from the cache when there).
"""

from __future__ import annotations

import multiprocessing as mp

from ..preview import DEFAULT_MAX_TRIANGLES
from ..preview.mesh_cache import cache_entry, cached_visual_model
from ..robot import Robot, load_visual_model


def start_mesh_prefetch(robot: Robot) -> mp.process.BaseProcess | None:
    """Start decimating the robot's preview meshes into the disk cache in a forked process, when they
    are not cached yet, so that a first run does it while it trains (about 3 s of CPU for Baxter).
    None when they are cached, or where processes cannot be forked."""
    s = robot.settings
    entry = cache_entry(s.urdf_path, s.package_dirs, DEFAULT_MAX_TRIANGLES)
    if entry is None or entry.is_file() or "fork" not in mp.get_all_start_methods():
        return None
    process = mp.get_context("fork").Process(target=preview_visual_model, args=(robot,), daemon=True)
    try:
        process.start()
    except OSError:
        return None
    return process


def preview_visual_model(robot: Robot, prefetch: mp.process.BaseProcess | None = None) -> object:
    """The robot's decimated visual model for the preview, from the on-disk mesh cache when there
    (:func:`~ipromp_pin.preview.mesh_cache.cached_visual_model`; loaded and decimated otherwise),
    after the ``prefetch`` process (:func:`start_mesh_prefetch`), if any, has finished."""
    if prefetch is not None:
        prefetch.join()
    s = robot.settings
    return cached_visual_model(
        robot.model, s.urdf_path, s.package_dirs, DEFAULT_MAX_TRIANGLES, lambda: load_visual_model(robot)
    )
