"""The preview's scene is packed by the compiled msgpack byte for byte as meshcat's own pure-Python
packing (umsgpack) packs it, typed arrays (umsgpack.Ext) included."""

from __future__ import annotations

import meshcat
import meshcat.animation
import meshcat.geometry as g
import numpy as np
import pytest
import umsgpack

from ipromp_pin.preview.recorder import SceneRecorder, packb


def test_packing_equals_meshcats_own_for_every_command_kind():
    recorder = SceneRecorder()
    sent = []
    original = recorder.send

    def spy(command):
        sent.append(command.lower())
        original(command)

    recorder.send = spy  # type: ignore[method-assign]
    viewer = meshcat.Visualizer(window=recorder)
    rng = np.random.default_rng(0)
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    viewer["a/mesh"].set_object(g.TriangularMeshGeometry(rng.random((5, 3)), faces))
    viewer["a/box"].set_object(g.Box([0.1, 0.2, 0.3]), g.MeshLambertMaterial(color=0xFF0000, opacity=0.5))
    viewer["a/box"].set_transform(np.eye(4))
    viewer["a/box"].set_property("visible", False)
    animation = meshcat.animation.Animation(default_framerate=30.0)
    for k in range(3):
        with animation.at_frame(viewer, k) as frame:
            frame["a/box"].set_transform(np.diag([1.0, 1.0, 1.0, 1.0]) + k * 0.1)
            frame["a/box"].set_property("scale", "vector3", [1.0, 2.0, 3.5 + k])
    viewer.set_animation(animation, play=False)
    viewer["a/mesh"].delete()
    kinds = {"set_object", "set_transform", "set_property", "set_animation", "delete"}
    assert {d["type"] for d in sent} == kinds
    for data in sent:
        assert packb(data) == umsgpack.packb(data)
    overlay = {"type": "ipromp_overlay", "state": {"x": [1.5, None, "s"], "n": 2**40, "neg": -3}}
    assert packb(overlay) == umsgpack.packb(overlay)
    assert umsgpack.unpackb(recorder.commands()[0]) is not None


def test_packing_refuses_what_meshcat_could_not_pack_either():
    with pytest.raises(TypeError):
        packb({"x": object()})
