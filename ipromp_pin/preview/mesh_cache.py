"""On-disk cache of a robot's decimated visual model, so that only the first preview pays for it.

Loading Baxter's visual meshes (~1-2 s) and decimating them (~3 s) is most of a preview's time and
gives the same result every run. :func:`cached_visual_model` keeps the decimated model in one
``.npz`` file per robot description and triangle budget in :func:`~ipromp_pin.cache.cache_dir`
(``meshes/``), keyed by a SHA-256 over the URDF's content, the content of every visual mesh file it
references, the budget and the versions of the decimation code, all computed without loading a
mesh. A hit rebuilds the geometry model from plain arrays (``allow_pickle=False``) in tens of
milliseconds; a missing, unreadable, corrupt or stale entry is a miss (the model is loaded and
decimated, and the entry rewritten); a read-only cache folder only means nothing is written.

Only what the preview draws is kept: per geometry object its name, parent joint and frame (by
name), placement, colour and either its decimated triangles or its primitive shape (box, sphere,
cylinder, capsule); a description with other geometry or materials is not cached.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

import coal
import fast_simplification
import numpy as np
import pinocchio as pin

from ..cache import cache_dir, write_atomically
from ..robot import Robot, add_tool_geometry, load_visual_model
from .meshes import (
    DEFAULT_MAX_TRIANGLES,
    count_triangles,
    decimated_meshes,
    display_mesh,
    mesh_arrays,
    simplify_visual_model,
)

__all__ = ["CACHE_VERSION", "cache_entry", "cached_visual_model", "visual_model_key"]

CACHE_VERSION = 1
"""Version of the cache entries' layout (part of the key: a new layout never reads an old file)."""

# primitive type -> (name, its parameters, built from them)
_PRIMITIVES: dict[type, tuple[str, Callable[[Any], list[float]], Callable[[np.ndarray], object]]] = {
    coal.Box: ("box", lambda g: list(2.0 * np.asarray(g.halfSide)), lambda p: coal.Box(*p)),
    coal.Sphere: ("sphere", lambda g: [g.radius], lambda p: coal.Sphere(p[0])),
    coal.Cylinder: ("cylinder", lambda g: [g.radius, 2.0 * g.halfLength], lambda p: coal.Cylinder(*p)),
    coal.Capsule: ("capsule", lambda g: [g.radius, 2.0 * g.halfLength], lambda p: coal.Capsule(*p)),
}
_BUILD = {kind: build for kind, _, build in _PRIMITIVES.values()}


def _mesh_file(uri: str, urdf_dir: Path, package_dirs: Sequence[str]) -> Path | None:
    """The file a URDF mesh URI refers to (``package://``, ``file://``, absolute or relative)."""
    if uri.startswith("package://"):
        rest = uri[len("package://") :]
        for folder in package_dirs:
            candidate = Path(folder) / rest
            if candidate.is_file():
                return candidate
        return None
    path = Path(uri[len("file://") :] if uri.startswith("file://") else uri)
    path = path if path.is_absolute() else urdf_dir / path
    return path if path.is_file() else None


def _file_digests(paths: list[Path], memo_path: Path | None) -> list[bytes] | None:
    """SHA-256 of the files' contents (None if one cannot be read). ``memo_path``, a JSON file, keeps
    the digests of files by path, size and modification time, so that an unchanged file is not read
    again (Baxter's visual meshes are 26 MB); it is only an optimisation: unreadable, it is ignored."""
    memo: dict[str, list] = {}
    if memo_path is not None:
        try:
            memo = json.loads(memo_path.read_text())
            if not isinstance(memo, dict):
                memo = {}
        except (OSError, ValueError):
            memo = {}
    out, changed = [], False
    for path in paths:
        try:
            st = path.stat()
            known = memo.get(str(path))
            if isinstance(known, list) and known[:2] == [st.st_size, st.st_mtime_ns]:
                out.append(bytes.fromhex(known[2]))
                continue
            digest = hashlib.sha256(path.read_bytes()).digest()
        except (OSError, ValueError, IndexError, TypeError):
            return None
        memo[str(path)] = [st.st_size, st.st_mtime_ns, digest.hex()]
        changed = True
        out.append(digest)
    if changed and memo_path is not None:
        text = json.dumps(memo)

        def write(tmp: Path) -> None:
            tmp.write_text(text)

        write_atomically(memo_path, write)
    return out


def visual_model_key(
    urdf_path: str | Path, package_dirs: Sequence[str], max_triangles: int, memo_path: Path | None = None
) -> str | None:
    """Cache key (hex SHA-256) of a description's decimated visual model, or None when a visual mesh
    file cannot be found (then nothing is cached). ``memo_path``: see :func:`_file_digests`."""
    urdf = Path(urdf_path)
    try:
        text = urdf.read_bytes()
        root = ET.fromstring(text)
    except (OSError, ET.ParseError):
        return None
    digest = hashlib.sha256()
    header = {
        "cache_version": CACHE_VERSION,
        "max_triangles": int(max_triangles),
        "fast_simplification": getattr(fast_simplification, "__version__", "?"),
        "pinocchio": pin.__version__,
    }
    digest.update(json.dumps(header, sort_keys=True).encode())
    digest.update(hashlib.sha256(text).digest())
    uris: list[str] = []
    paths: list[Path] = []
    for visual in root.iter("visual"):
        for mesh in visual.iter("mesh"):
            uri = mesh.get("filename")
            path = None if uri is None else _mesh_file(uri, urdf.parent, package_dirs)
            if uri is None or path is None:
                return None
            uris.append(uri)
            paths.append(path.resolve())
    digests = _file_digests(paths, memo_path)
    if digests is None:
        return None
    for uri, file_digest in zip(uris, digests, strict=True):
        digest.update(uri.encode() + b"\0" + file_digest)
    return digest.hexdigest()


def _to_arrays(
    model: pin.Model, geometry: pin.GeometryModel, triangles: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, np.ndarray] | None:
    """Plain arrays of a decimated geometry model whose meshes' triangles are ``triangles`` (by
    object name), or None when it holds something not cached."""
    objects: list[dict] = []
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    for obj in geometry.geometryObjects:
        if type(obj.meshMaterial).__name__ != "GeometryNoMaterial" or obj.meshTexturePath:
            return None
        entry = {
            "name": obj.name,
            "joint": model.names[obj.parentJoint],
            "frame": model.frames[obj.parentFrame].name,
            "placement": obj.placement.homogeneous.tolist(),
            "color": [float(c) for c in obj.meshColor],
            "override_material": bool(obj.overrideMaterial),
        }
        shape = obj.geometry
        if isinstance(shape, coal.BVHModelBase):
            if obj.meshPath or not np.allclose(obj.meshScale, 1.0):
                return None  # not decimated (still refers to its file)
            v, f = triangles[obj.name] if obj.name in triangles else mesh_arrays(shape)
            entry["mesh"] = len(vertices)
            vertices.append(v)
            faces.append(f)
        elif type(shape) in _PRIMITIVES:
            kind, params, _ = _PRIMITIVES[type(shape)]
            entry["primitive"] = kind
            entry["params"] = [float(x) for x in params(shape)]
        else:
            return None
        objects.append(entry)
    arrays = {"objects": np.array(json.dumps(objects))}
    for i, (v, f) in enumerate(zip(vertices, faces, strict=True)):
        arrays[f"v{i}"] = v
        arrays[f"f{i}"] = f
    return arrays


def _from_arrays(model: pin.Model, arrays) -> pin.GeometryModel:
    """The geometry model of :func:`_to_arrays`'s arrays (raises KeyError / ValueError if invalid)."""
    objects = json.loads(str(arrays["objects"][()]))
    geometry = pin.GeometryModel()
    for entry in objects:
        if not (model.existJointName(entry["joint"]) and model.existFrame(entry["frame"])):
            raise ValueError(f"joint {entry['joint']} or frame {entry['frame']} not in the model")
        placement = np.asarray(entry["placement"], dtype=float)
        if "mesh" in entry:
            v = np.asarray(arrays[f"v{entry['mesh']}"], dtype=float)
            f = np.asarray(arrays[f"f{entry['mesh']}"], dtype=np.int64)
            if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or not np.all(np.isfinite(v)):
                raise ValueError("bad mesh arrays")
            if f.size and (f.min() < 0 or f.max() >= len(v)):
                raise ValueError("face index out of range")
            shape = display_mesh(v, f)
        else:
            shape = _BUILD[entry["primitive"]](np.asarray(entry["params"], dtype=float))
        obj = pin.GeometryObject(
            entry["name"],
            model.getJointId(entry["joint"]),
            model.getFrameId(entry["frame"]),
            pin.SE3(placement[:3, :3], placement[:3, 3]),
            shape,
            "",
            np.ones(3),
            bool(entry["override_material"]),
            np.asarray(entry["color"], dtype=float),
        )
        geometry.addGeometryObject(obj)
    return geometry


def cache_entry(
    urdf_path: str | Path, package_dirs: Sequence[str], max_triangles: int, folder: Path | None = None
) -> Path | None:
    """The cache file of a description's decimated visual model (it may not exist yet), or None when
    the description cannot be cached (a visual mesh file cannot be found)."""
    folder = folder or cache_dir("meshes")
    key = visual_model_key(urdf_path, package_dirs, max_triangles, folder / "file_digests.json")
    return folder / f"{key}.npz" if key else None


def cached_visual_model(
    model: pin.Model,
    urdf_path: str | Path,
    package_dirs: Sequence[str],
    max_triangles: int,
    load: Callable[[], pin.GeometryModel],
    *,
    folder: Path | None = None,
) -> pin.GeometryModel:
    """The visual model of a robot decimated to about ``max_triangles`` triangles, from the cache.

    Args:
        model: The robot's kinematic model (parent joints and frames are resolved in it by name).
        urdf_path, package_dirs: The robot description (what the key is computed from).
        max_triangles: Triangle budget of :func:`~ipromp_pin.preview.meshes.simplify_visual_model`.
        load: Loads the full visual model (called on a miss only).
        folder: Cache folder (default: :func:`~ipromp_pin.cache.cache_dir` ``("meshes")``).

    Returns:
        A decimated geometry model (mesh scales baked in, no mesh file references), the same with or
        without the cache.
    """
    path = cache_entry(urdf_path, package_dirs, max_triangles, folder)
    if path is not None and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as arrays:
                return _from_arrays(model, arrays)
        except (OSError, ValueError, KeyError, TypeError, EOFError, RuntimeError, zipfile.BadZipFile):
            pass  # corrupt or stale: rebuilt and rewritten below
    visual = load()
    decimated = simplify_visual_model(visual, max_triangles)
    if path is not None and count_triangles(decimated) > 0:
        arrays = _to_arrays(model, decimated, decimated_meshes(visual, max_triangles))
        if arrays is not None:

            def save(tmp: Path) -> None:
                with tmp.open("wb") as f:
                    np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy stubs: a key could be allow_pickle

            write_atomically(path, save)
    return decimated


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
    # the cache holds the URDF's meshes (its key is the URDF's); the settings' [tool] is added after
    urdf_only = partial(load_visual_model, robot, tool=False)
    visual = cached_visual_model(robot.model, s.urdf_path, s.package_dirs, DEFAULT_MAX_TRIANGLES, urdf_only)
    add_tool_geometry(robot.model, visual, s, pairs=False)
    return visual
