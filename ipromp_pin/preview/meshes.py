"""Mesh geometry of the preview: decimation of the robot's visual meshes, tube and sphere meshes.

The robot's visual meshes are decimated with quadric edge collapse (``fast_simplification``) so that
an offline page stays small; decimated meshes are cached per source mesh and target. Paths (hand,
predicted end effector) are drawn as closed tube meshes, points as sphere meshes. Meshes are
``(vertices (V, 3) in [m], faces (F, 3) vertex indices)`` pairs.
"""

from __future__ import annotations

from typing import Any

import coal
import fast_simplification
import numpy as np
import pinocchio as pin

from .content import preview_error

__all__ = [
    "DEFAULT_MAX_TRIANGLES",
    "count_triangles",
    "decimated_meshes",
    "display_mesh",
    "mesh_arrays",
    "simplify_visual_model",
    "sphere_mesh",
    "tube_mesh",
]

#: Default triangle budget of the robot's visual meshes (Baxter: a 3.7 MB offline page).
DEFAULT_MAX_TRIANGLES = 100_000

# Explicit module-level cache of meshes, keyed by (mesh file, scale, triangles, target triangles or
# None for the original):
# decimating Baxter's ~400k visual triangles takes a few seconds, and a live preview or a batch of
# offline previews reuses the same meshes.  Cleared with ``_SIMPLIFIED_MESHES.clear()``.
_SIMPLIFIED_MESHES: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def mesh_arrays(geometry: Any) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3), faces (F, 3) int64) of a coal BVH mesh."""
    vertices = np.asarray(geometry.vertices(), dtype=float)
    faces = np.empty((geometry.num_tris, 3), dtype=np.int64)
    for k in range(geometry.num_tris):
        tri = geometry.tri_indices(k)
        faces[k] = (tri[0], tri[1], tri[2])
    return vertices, faces


def display_mesh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A coal mesh (vertices (V, 3) in [m], faces (F, 3)) for display only: its bounding-volume tree
    is not built (``endModel`` is not called: that takes about 0.3 s for Baxter's 100,000 preview
    triangles and only collision queries need it), so it must not be used for collision checks."""
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(vertices))
    bvh.addVertices(np.ascontiguousarray(vertices, dtype=float))
    bvh.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    return bvh


def _decimated(obj: pin.GeometryObject, target: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh object, scale baked in, decimated to about ``target`` triangles."""
    scale = np.asarray(obj.meshScale, dtype=float)
    source = (obj.meshPath, tuple(scale), obj.geometry.num_tris)
    if source + (None,) not in _SIMPLIFIED_MESHES:
        vertices, faces = mesh_arrays(obj.geometry)
        _SIMPLIFIED_MESHES[source + (None,)] = (vertices * scale, faces)
    key = source + (target,)
    if key not in _SIMPLIFIED_MESHES:
        # The decimation's target only stops it early: a run that ended above its target went
        # through every iteration, so any lower target gives the very same mesh; reuse it.
        for (*other, done), mesh in list(_SIMPLIFIED_MESHES.items()):
            if tuple(other) == source and done is not None and done >= target and len(mesh[1]) > done:
                _SIMPLIFIED_MESHES[key] = mesh
                return mesh
        vertices, faces = _SIMPLIFIED_MESHES[source + (None,)]
        if target < len(faces):
            vertices, faces = fast_simplification.simplify(
                vertices.astype(np.float32), faces.astype(np.int32), target_count=target
            )
        _SIMPLIFIED_MESHES[key] = (np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64))
    return _SIMPLIFIED_MESHES[key]


def simplify_visual_model(
    visual_model: pin.GeometryModel, max_triangles: int = DEFAULT_MAX_TRIANGLES
) -> pin.GeometryModel:
    """Copy of ``visual_model`` whose meshes have at most about ``max_triangles`` triangles in total
    (``visual_model`` itself when it already is such a model: within the budget, no mesh files).

    Meshes are decimated with quadric edge collapse (``fast_simplification``) by a common ratio;
    meshes that cannot be reduced that far (many small parts) keep more triangles, and the ratio
    of the others is lowered to stay within the budget (a few passes). Primitives (boxes,
    cylinders, spheres) are kept as they are. Mesh scales are baked into the vertices and mesh file
    references dropped, so that meshcat receives the decimated triangles instead of the original
    files. Colours are the description's ``meshColor``. The meshes are for display only
    (:func:`display_mesh`: no collision queries on them).
    """
    if max_triangles < 100:
        raise preview_error("max_triangles", f"must be >= 100, got {max_triangles}")
    meshes = [g for g in visual_model.geometryObjects if isinstance(g.geometry, coal.BVHModelBase)]
    total = sum(g.geometry.num_tris for g in meshes)
    if total <= 1.05 * max_triangles and all(g.meshPath == "" and np.all(g.meshScale == 1.0) for g in meshes):
        return visual_model  # already decimated (e.g. from the mesh cache): nothing to do
    decimated = decimated_meshes(visual_model, max_triangles)
    result = pin.GeometryModel()
    for obj in visual_model.geometryObjects:
        new = pin.GeometryObject(obj)
        if obj.name in decimated:
            new.geometry = display_mesh(*decimated[obj.name])
            new.meshPath = ""
            new.meshScale = np.ones(3)
        result.addGeometryObject(new)
    return result


def decimated_meshes(
    visual_model: pin.GeometryModel, max_triangles: int = DEFAULT_MAX_TRIANGLES
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The triangles ``(vertices (V, 3) in [m], faces (F, 3))`` of every mesh object of
    ``visual_model`` (by name), scale baked in, decimated as :func:`simplify_visual_model` does."""
    meshes = [g for g in visual_model.geometryObjects if isinstance(g.geometry, coal.BVHModelBase)]
    total = sum(g.geometry.num_tris for g in meshes)
    ratio = min(1.0, max_triangles / total) if total else 1.0
    targets: dict[str, int] = {}
    for _ in range(4):
        targets = {g.name: max(12, int(g.geometry.num_tris * ratio)) for g in meshes}
        reached = sum(len(_decimated(g, targets[g.name])[1]) for g in meshes)
        if reached <= 1.05 * max_triangles or ratio * total < 12 * len(meshes):
            break
        ratio *= max_triangles / reached
    return {g.name: _decimated(g, targets[g.name]) for g in meshes}


def count_triangles(geometry_model: pin.GeometryModel) -> int:
    """Total number of mesh triangles of a geometry model (primitives not counted)."""
    return sum(
        g.geometry.num_tris
        for g in geometry_model.geometryObjects
        if isinstance(g.geometry, coal.BVHModelBase)
    )


def tube_mesh(
    points: np.ndarray, radius: float | np.ndarray, sides: int = 12
) -> tuple[np.ndarray, np.ndarray]:
    """Closed tube mesh around a polyline, with end caps.

    Args:
        points: (M, 3) polyline in [m]; repeated consecutive points are dropped (a single point
            gives a sphere).
        radius: Tube radius in [m], scalar or (M,) per point.
        sides: Number of vertices of each ring around the path.

    Returns:
        ``(vertices (V, 3) in [m], faces (F, 3))``: ring ``i`` is ``vertices[i * sides:(i + 1) * sides]``,
        the two cap centres come last.
    """
    pts = np.asarray(points, dtype=float)
    radii = np.broadcast_to(np.asarray(radius, dtype=float), (len(pts),))
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9
    pts, radii = pts[keep], radii[keep]
    if len(pts) < 2:
        return sphere_mesh(pts[0], float(radii[0]))
    tangents = np.gradient(pts, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    # Parallel transport of a normal along the path (no twist).
    normals = np.empty_like(pts)
    axis = np.eye(3)[int(np.argmin(np.abs(tangents[0])))]
    normal = np.cross(tangents[0], axis)
    normal /= np.linalg.norm(normal)
    for i, tangent in enumerate(tangents):
        projected = normal - np.dot(normal, tangent) * tangent
        norm = np.linalg.norm(projected)
        if norm < 1e-6:
            projected = np.cross(tangent, np.eye(3)[int(np.argmin(np.abs(tangent)))])
            norm = np.linalg.norm(projected)
        normal = projected / norm
        normals[i] = normal
    binormals = np.cross(tangents, normals)
    angles = 2.0 * np.pi * np.arange(sides) / sides
    ring = (
        pts[:, None, :]
        + radii[:, None, None]
        * (
            np.cos(angles)[None, :, None] * normals[:, None, :]
            + np.sin(angles)[None, :, None] * binormals[:, None, :]
        )
    ).reshape(-1, 3)
    m = len(pts)
    ii, kk = np.meshgrid(np.arange(m - 1), np.arange(sides), indexing="ij")
    a = ii * sides + kk
    b = ii * sides + (kk + 1) % sides
    c = a + sides
    d = b + sides
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    start, end = len(ring), len(ring) + 1
    kr = np.arange(sides)
    caps = np.concatenate(
        [
            np.stack([np.full(sides, start), (kr + 1) % sides, kr], -1),
            np.stack([np.full(sides, end), (m - 1) * sides + kr, (m - 1) * sides + (kr + 1) % sides], -1),
        ]
    )
    vertices = np.vstack([ring, pts[0], pts[-1]])
    return vertices, np.vstack([faces, caps])


def sphere_mesh(center: np.ndarray, radius: float, n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Closed sphere mesh of ``radius`` [m] around ``center`` (3,) [m].

    ``n - 1`` rings of ``2 n`` vertices (at polar angles ``pi k / n``) between two poles; returns
    ``(vertices (V, 3) in [m], faces (F, 3))``, faces wound outwards.
    """
    theta = np.linspace(0.0, np.pi, n + 1)[1:-1]
    phi = 2.0 * np.pi * np.arange(2 * n) / (2 * n)
    ring = np.stack(
        [
            np.outer(np.sin(theta), np.cos(phi)),
            np.outer(np.sin(theta), np.sin(phi)),
            np.outer(np.cos(theta), np.ones_like(phi)),
        ],
        -1,
    ).reshape(-1, 3)
    vertices = np.vstack([ring, [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]) * radius + np.asarray(center, dtype=float)
    rows, cols = len(theta), len(phi)
    ii, kk = np.meshgrid(np.arange(rows - 1), np.arange(cols), indexing="ij")
    a = ii * cols + kk
    b = ii * cols + (kk + 1) % cols
    faces = [
        np.stack([a, b + cols, b], -1).reshape(-1, 3),
        np.stack([a, a + cols, b + cols], -1).reshape(-1, 3),
    ]
    top, bottom = len(ring), len(ring) + 1
    kr = np.arange(cols)
    faces.append(np.stack([np.full(cols, top), kr, (kr + 1) % cols], -1))
    last = (rows - 1) * cols
    faces.append(np.stack([np.full(cols, bottom), last + (kr + 1) % cols, last + kr], -1))
    return vertices, np.vstack(faces)
