"""The joints' torque usage and the held object in the preview: the panel's torque data on the
animation's time base, the object drawn in the gripper frame and shown only while the robot holds it
(``robot_gives``: until the hand-over; ``robot_receives``: from it on), in the offline page and the
replay timeline."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_body_preview import animation_tracks
from test_preview import load_baxter, make_content, objects_by_path, scene_commands

from ipromp_pin import preview
from ipromp_pin.exceptions import DataError
from ipromp_pin.preview.object_scene import OBJECT_NODE, shape_transform
from ipromp_pin.preview.scene import overlay_state
from ipromp_pin.preview.timeline import TimelineEvent, render_timeline_html
from ipromp_pin.preview.torques import HeldObject, TorqueTrack, torque_panel, usage_color

FPS = 30.0
SHAPE = f"/meshcat/{OBJECT_NODE}/shape"


@pytest.fixture(scope="module")
def baxter():
    return load_baxter()


def make_track(content: preview.PreviewContent, offset: float, held: np.ndarray) -> TorqueTrack:
    n = content.t_s.size
    ratio = np.abs(np.sin(np.linspace(0.0, 3.0, n)[:, None] * np.arange(1, 8)[None, :])) * 0.95
    return TorqueTrack(
        content.t_s + offset, ratio, content.joint_names, np.full(7, 50.0), 0.9, held, "rod (0.42 kg)"
    )


def spanner(handover_s: float, gives: bool) -> HeldObject:
    return HeldObject(
        "spanner_handover", 0.25, "left_gripper", "box", [0.01, 0.04, 0.22], np.array([0.0, 0.0, 0.07]),
        held_from_s=None if gives else handover_s, held_until_s=handover_s if gives else None,
    )  # fmt: skip


def test_held_object_holds_until_or_from_the_handover():
    t = np.array([0.0, 2.0, 2.5, 3.0])
    assert spanner(2.5, True).held(t).tolist() == [True, True, True, False]
    assert spanner(2.5, False).held(t).tolist() == [False, False, True, True]
    with pytest.raises(DataError, match="held_object.dims_m"):
        HeldObject("x", 1.0, "left_gripper", "cylinder", [0.01, 0.1, 0.2], np.zeros(3))
    with pytest.raises(DataError, match="held_object.kind"):
        HeldObject("x", 1.0, "left_gripper", "cone", [0.01], np.zeros(3))


def test_cylinder_axis_is_turned_onto_the_objects_axis():
    for axis in range(3):
        obj = HeldObject(
            "rod", 0.4, "left_gripper", "cylinder", [0.01, 0.5], np.array([0.0, 0.0, 0.02]), axis
        )
        T = shape_transform(obj)
        assert np.allclose(T[:3, 1], np.eye(3)[axis])  # meshcat's cylinder axis is its local y
        assert np.allclose(T[:3, 3], [0.0, 0.0, 0.02]) and np.isclose(np.linalg.det(T[:3, :3]), 1.0)


def test_torque_track_validates_and_the_panel_is_on_the_animation_clock(baxter):
    content = make_content(*baxter)
    n = content.t_s.size
    track = make_track(content, 1.0, np.ones(n, bool))
    assert track.peak.shape == (7,) and track.payload_at(0) == "holding rod (0.42 kg)"
    panel = torque_panel(track)
    assert (
        panel["t_s"][0] == pytest.approx(track.t_s[0])
        and len(panel["ratio"]) == n
        and len(panel["ratio"][0]) == 7
    )
    j = int(np.argmax(track.peak))
    assert panel["peak"][j] == pytest.approx(track.ratio.max(), abs=1e-4)
    assert panel["peak_t_s"][j] == pytest.approx(track.t_s[track.ratio[:, j].argmax()], abs=1e-3)
    assert [usage_color(r, 0.9) for r in (0.5, 0.8, 0.95)] == ["ok", "high", "over"]
    with pytest.raises(DataError, match="torques.ratio"):
        TorqueTrack(track.t_s, track.ratio[:, :3], track.joint_names, track.limit_nm, 0.9, track.held)
    with pytest.raises(DataError, match="torques.held"):
        TorqueTrack(track.t_s, track.ratio, track.joint_names, track.limit_nm, 0.9, track.held[:-1])
    state = overlay_state(content.replace(torques=track))
    assert state["torques"]["payload"] == "rod (0.42 kg)" and overlay_state(content)["torques"] is None


def frame_poses(content: preview.PreviewContent, times: np.ndarray) -> np.ndarray:
    model = content.model
    data = model.createData()
    fid = model.getFrameId("left_gripper")
    out = []
    for q in content.configurations(times):
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[fid].translation.copy())
    return np.array(out)


def check_object_scene(commands: list[dict], content: preview.PreviewContent, offset: float, gives: bool):
    """The shape is drawn, follows the gripper frame, and is visible exactly while held."""
    assert SHAPE in objects_by_path(commands)
    tracks = animation_tracks(commands)
    moves = tracks[f"/meshcat/{OBJECT_NODE}"][".position"]
    times = np.array([k["time"] / FPS for k in moves])
    np.testing.assert_allclose([k["value"] for k in moves], frame_poses(content, times), atol=1e-6)
    keys = tracks[SHAPE][".visible"]
    assert keys[0]["time"] == 0 and keys[0]["value"] is gives  # held at the start only when given
    handover = content.held_object.held_until_s if gives else content.held_object.held_from_s
    for key, nxt in zip(keys, keys[1:] + [None], strict=True):  # each key holds until the next one
        t0 = key["time"] / FPS + offset
        t1 = (nxt["time"] / FPS + offset) if nxt else times[-1] + offset
        held = (t0 <= handover + 1e-9) if gives else (t0 >= handover - 1e-9)
        assert key["value"] is held
        if nxt is not None:
            assert t0 <= handover + 1e-9 <= t1 + 1 / FPS
    assert len(keys) == 2  # one change, at the hand-over


@pytest.mark.parametrize("gives", [True, False])
def test_offline_page_draws_the_object_only_while_held(baxter, gives):
    base = make_content(*baxter)
    handover = 1.0 + 2.0  # human's clock: the observation ends at 1 s, the hand-over 2 s later
    content = base.replace(held_object=spanner(handover, gives))
    html = preview.render_html(content, max_triangles=20_000)
    check_object_scene(scene_commands(html), content, 1.0, gives)
    assert "ipromp-torques" in html  # the panel's script is on the page


def test_the_object_is_not_drawn_without_one(baxter):
    objects = objects_by_path(
        scene_commands(preview.render_html(make_content(*baxter), max_triangles=20_000))
    )
    assert not any(p.startswith("/meshcat/object") for p in objects)


def test_timeline_draws_the_received_object_from_the_handover_on(baxter):
    base = make_content(*baxter)
    shifted = base.replace(t_s=base.t_s + 1.0, observed_until_s=None, held_object=spanner(3.5, False))
    events = [TimelineEvent(t_s=1.0, observed_until_s=1.0, task="handover_cup", committed=True)]
    html = render_timeline_html(shifted, events, motion_s=4.0, max_triangles=20_000)
    check_object_scene(scene_commands(html), shifted, 0.0, False)


def test_content_rejects_an_object_on_an_unknown_frame(baxter):
    obj = spanner(2.0, True)
    obj.frame = "no_such_frame"
    with pytest.raises(DataError, match="held_object"):
        make_content(*baxter, held_object=obj)
