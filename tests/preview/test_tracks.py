"""Animation tracks put whole (ipromp_pin.preview.tracks) give the keys meshcat's per-frame API gives:
the same frames, positions and quaternions (its convention, w >= 0), properties merged in frame
order."""

from __future__ import annotations

import meshcat
import meshcat.animation as ma
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipromp_pin.preview.recorder import SceneRecorder
from ipromp_pin.preview.tracks import put_property, put_transforms, quaternions_wxyz


def _placements(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    T[2, :3, :3] = np.diag([1.0, -1.0, -1.0])  # a half turn: the eigen-decomposition's hard case
    T[3, :3, :3] = np.eye(3)
    T[:, :3, 3] = rng.normal(size=(n, 3))
    return T


def test_whole_tracks_equal_meshcats_per_frame_keys():
    viewer = meshcat.Visualizer(window=SceneRecorder())
    T = _placements(12, 0)
    reference = ma.Animation(default_framerate=25.0)
    for k in range(T.shape[0]):
        with reference.at_frame(viewer, k) as frame:
            frame["robot/link"].set_transform(T[k])
            frame["robot/link"].set_property("scale", "vector3", [1.0, 2.0, float(k)])
            if k in (0, 5, 9):
                frame["robot/link"].set_property("visible", "boolean", k != 5)
    whole = ma.Animation(default_framerate=25.0)
    path = viewer["robot/link"].path
    frames = list(range(T.shape[0]))
    put_transforms(whole, path, frames, T)
    put_property(whole, path, "scale", "vector3", frames, [[1.0, 2.0, float(k)] for k in frames])
    put_property(whole, path, "visible", "boolean", [9, 0], [True, True])  # merged in frame order
    put_property(whole, path, "visible", "boolean", [5], [False])
    [ref], [got] = reference.lower(), whole.lower()
    assert ref["path"] == got["path"] and ref["clip"]["fps"] == got["clip"]["fps"]
    tracks = {t["name"]: t for t in got["clip"]["tracks"]}
    for track in ref["clip"]["tracks"]:
        mine = tracks[track["name"]]
        assert mine["type"] == track["type"]
        assert [k["time"] for k in mine["keys"]] == [k["time"] for k in track["keys"]]
        np.testing.assert_allclose(
            np.array([k["value"] for k in mine["keys"]], dtype=float),
            np.array([k["value"] for k in track["keys"]], dtype=float),
            atol=1e-12,
        )


def test_quaternions_follow_meshcats_convention_and_refuse_a_length_mismatch():
    T = _placements(20, 1)
    q = quaternions_wxyz(T)
    assert np.all(q[:, 0] >= 0.0) and np.allclose(np.linalg.norm(q, axis=1), 1.0)
    back = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()
    np.testing.assert_allclose(back, T[:, :3, :3], atol=1e-9)
    with pytest.raises(ValueError, match="2 frames for 1 values"):
        path = meshcat.Visualizer(window=SceneRecorder())["x"].path
        put_property(ma.Animation(), path, "p", "number", [0, 1], [1])
