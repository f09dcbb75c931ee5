"""Tests of the 3-D preview without a browser: scene content, offline page, live server."""

from __future__ import annotations

import asyncio
import base64
import json
import re
import socket
import urllib.request
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
import umsgpack

from ipromp_pin import preview
from ipromp_pin.exceptions import DataError
from ipromp_pin.preview.scene import RobotView, scene_points
from ipromp_pin.robot import ee_positions, load_robot, load_visual_model

ARM = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
TASKS = ("handover_cup", "handover_rod", "handover_tape")


def load_baxter(kind: pin.GeometryType = pin.GeometryType.VISUAL) -> tuple[pin.Model, pin.GeometryModel]:
    """Baxter's model and visual (or collision) geometry, through the project's robot settings."""
    robot = load_robot("baxter_left")
    geometry = load_visual_model(robot) if kind == pin.GeometryType.VISUAL else robot.collision_model
    return robot.model, geometry


def make_content(model: pin.Model, visual: pin.GeometryModel, **changes) -> preview.PreviewContent:
    """A hand-over preview: the left arm reaching forward, the human hand coming to meet it."""
    t = np.linspace(0.0, 3.0, 61)
    s = 0.5 - 0.5 * np.cos(np.pi * t / t[-1])
    q0 = np.array([0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0])
    q1 = np.array([0.6, -0.2, -0.3, 1.2, 0.2, 0.6, 0.0])
    q = q0 + s[:, None] * (q1 - q0)
    q_full = pin.neutral(model)
    data = model.createData()
    frame = model.getFrameId("left_gripper")
    ee = []
    for qi in q:
        full = q_full.copy()
        for name, value in zip(ARM, qi, strict=True):
            full[model.joints[model.getJointId(name)].idx_q] = value
        pin.framesForwardKinematics(model, data, full)
        ee.append(data.oMf[frame].translation.copy())
    ee = np.array(ee)
    rng = np.random.default_rng(0)
    samples = ee[None] + np.cumsum(rng.normal(0.0, 0.003, (12, len(t), 3)), axis=1)
    hand_t = np.linspace(0.0, 4.0, 40)  # the human's motion (4 s) lasts longer than the robot's (3 s)
    start = ee[-1] + np.array([0.5, -0.3, -0.2])
    hand = start + (ee[-1] + np.array([0.05, 0.0, 0.0]) - start) * (hand_t / hand_t[-1])[:, None]
    kwargs = dict(
        model=model,
        visual_model=visual,
        t_s=t,
        q=q,
        joint_names=ARM,
        q_full=q_full,
        ee_mean=ee,
        ee_samples=samples,
        ee_truth=ee + np.array([0.0, 0.02, 0.02]),
        hand_path=hand,
        hand_t_s=hand_t,
        observed_until_s=1.0,
        human_duration_s=4.0,
        human_duration_source="recorded",
        handover_point=ee[-1],
        task="handover_cup",
        tasks=TASKS,
        posterior=[0.82, 0.13, 0.05],
        feasibility=[
            ("joint limits", True, "margin 0.12 rad"),
            ("self-collision", False, "forearm vs torso"),
            ("hand distance", True, "human hand position unknown", "skip", False),
        ],
        collision_links=["left_lower_forearm"],
        near_limit_joints=["left_e1"],
    )
    kwargs.update(changes)
    return preview.PreviewContent(**kwargs)


PANDA_ARM = tuple(f"panda_joint{i}" for i in range(1, 8))


def make_panda_content() -> preview.PreviewContent:
    """A Franka Panda (the shipped ``panda`` settings) reaching from its ready pose towards a hand."""
    robot = load_robot("panda")
    t = np.linspace(0.0, 2.0, 41)
    s = 0.5 - 0.5 * np.cos(np.pi * t / t[-1])
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    q1 = np.array([0.3, 0.2, 0.0, -1.8, 0.0, 2.0, 0.785])
    q = q0 + s[:, None] * (q1 - q0)
    ee = ee_positions(robot, q)
    hand_t = np.linspace(0.0, 2.5, 30)
    start = ee[-1] + np.array([0.35, 0.1, 0.1])
    hand = start + (ee[-1] + np.array([0.05, 0.0, 0.0]) - start) * (hand_t / hand_t[-1])[:, None]
    return preview.PreviewContent(
        model=robot.model,
        visual_model=load_visual_model(robot),
        t_s=t,
        q=q,
        joint_names=PANDA_ARM,
        q_full=robot.full_configuration(q[0]),
        ee_mean=ee,
        hand_path=hand,
        hand_t_s=hand_t,
        observed_until_s=0.5,
        handover_point=ee[-1],
        task="handover",
        tasks=["handover"],
        posterior=[1.0],
        title="panda",
    )


@pytest.fixture(scope="module")
def baxter() -> tuple[pin.Model, pin.GeometryModel]:
    return load_baxter()


@pytest.fixture(scope="module")
def content(baxter) -> preview.PreviewContent:
    return make_content(*baxter)


@pytest.fixture(scope="module")
def page(content, tmp_path_factory) -> Path:
    return preview.write_html(content, tmp_path_factory.mktemp("preview") / "preview.html")


def scene_commands(html: str) -> list[dict]:
    match = re.search(r'<script type="application/json" id="ipromp-scene">(.*?)</script>', html, re.S)
    assert match is not None
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(match.group(1))]


def objects_by_path(commands: list[dict]) -> dict[str, dict]:
    return {c["path"]: c for c in commands if c["type"] == "set_object"}


# -- content validation ----------------------------------------------------------------------------


def test_content_derives_std_from_samples(content):
    assert content.ee_std is not None and content.ee_std.shape == content.ee_mean.shape
    assert np.all(content.ee_std > 0.0)
    assert content.hand_observed_count() == int(np.sum(content.hand_t_s <= 1.0))
    assert content.feasibility[1] == preview.FeasibilityCheck(
        "self-collision", False, "forearm vs torso", "fail", True
    )
    assert content.feasibility[2].status == "skip" and not content.feasibility[2].required


def test_observed_fraction_is_of_the_human_motion(content):
    assert content.duration_s == pytest.approx(3.0)  # the robot trajectory
    assert content.observed_fraction() == pytest.approx(1.0 / 4.0)  # of the human's 4 s, not 1 / 3
    assert content.replace(human_duration_s=None).observed_fraction() is None
    assert content.replace(observed_until_s=9.0).observed_fraction() == 1.0


def test_configurations_interpolate_arm_joints(content):
    qs = content.configurations(np.array([0.0, 1.5, 3.0]))
    iq = content.model.joints[content.model.getJointId("left_e1")].idx_q
    assert qs.shape == (3, content.model.nq)
    assert qs[0, iq] == pytest.approx(content.q[0, 3])
    assert qs[2, iq] == pytest.approx(content.q[-1, 3])
    other = content.model.joints[content.model.getJointId("right_e1")].idx_q
    assert np.all(qs[:, other] == content.q_full[other])


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"q": np.zeros((61, 6))}, "q"),
        ({"q": np.zeros((60, 7))}, "q"),
        ({"joint_names": ARM[:-1] + ("left_w9",)}, "joint_names"),
        ({"t_s": np.r_[np.linspace(0, 3, 60), 2.0]}, "t_s"),
        ({"posterior": [0.5, 0.4, 0.3]}, "posterior"),
        ({"posterior": [0.5, 0.5]}, "posterior"),
        ({"task": "handover_bottle"}, "task"),
        ({"ee_samples": np.zeros((4, 10, 3))}, "ee_samples"),
        ({"hand_t_s": np.linspace(0, 1, 5)}, "hand_t_s"),
        ({"hand_observed_index": 99}, "hand_observed_index"),
        ({"ee_mean": np.full((61, 3), np.nan), "ee_samples": None, "ee_std": None}, "ee_mean"),
        ({"near_limit_joints": ["elbow"]}, "near_limit_joints"),
        ({"feasibility": [("only a name",)]}, "feasibility"),
        ({"feasibility": [("limits", True, "", "skipped")]}, "feasibility"),
        ({"feasibility": [("limits", True, "", "fail")]}, "feasibility"),
        ({"human_duration_s": 0.0}, "human_duration_s"),
        ({"q_full": np.zeros(3)}, "q_full"),
    ],
)
def test_content_rejects_bad_input(baxter, changes, field):
    with pytest.raises(DataError, match=f"field '{field}'"):
        make_content(*baxter, **changes)


def test_unknown_collision_link_is_an_error(baxter):
    with pytest.raises(DataError, match="left_tentacle"):
        make_content(*baxter, collision_links=["left_tentacle"])
    # Geometry names of the collision or visual model are accepted as well as link names.
    assert make_content(*baxter, collision_links=["left_wrist_0"]).collision_links == ("left_wrist_0",)


# -- geometry --------------------------------------------------------------------------------------


def test_tube_is_a_closed_valid_mesh():
    points = np.stack([np.linspace(0, 1, 20), np.sin(np.linspace(0, 3, 20)), np.zeros(20)], -1)
    vertices, faces = preview.tube_mesh(points, np.linspace(0.01, 0.05, 20), sides=8)
    assert faces.min() >= 0 and faces.max() < len(vertices)
    # Every edge of a closed surface is shared by exactly two triangles.
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    # Ring vertices lie at the requested radius from the path.
    assert np.linalg.norm(vertices[0] - points[0]) == pytest.approx(0.01)
    assert np.linalg.norm(vertices[8 * 19] - points[19]) == pytest.approx(0.05)


def test_sphere_is_a_closed_round_mesh_wound_outwards():
    center = np.array([1.0, 2.0, 3.0])
    vertices, faces = preview.sphere_mesh(center, 0.5)
    assert np.allclose(np.linalg.norm(vertices - center, axis=1), 0.5)
    assert np.ptp(vertices[:, 2]) == pytest.approx(1.0)  # a ball, not a flat double cone
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)
    v = vertices - center
    volume = np.einsum("ij,ij->i", v[faces[:, 0]], np.cross(v[faces[:, 1]], v[faces[:, 2]])).sum() / 6
    assert 0.95 * (4 / 3 * np.pi * 0.125) < volume < 4 / 3 * np.pi * 0.125  # positive: outward normals


def test_camera_distance_follows_the_scene_size():
    small = np.array([[0.0, 0.0, 0.0], [0.4, 0.3, 0.8]])
    centre, eye = preview.camera_view(small)
    assert centre == pytest.approx([0.2, 0.15, 0.4])
    assert np.dot(eye, [1.0, 0.0, 0.0]) > 0 and eye[2] > 0  # in front of the robot, above
    big_centre, big_eye = preview.camera_view(small * 3.0)
    assert big_centre == pytest.approx(3.0 * centre)
    assert np.linalg.norm(big_eye) == pytest.approx(3.0 * np.linalg.norm(eye))
    # the circumscribed sphere spans the vertical field of view
    radius = 0.5 * np.linalg.norm(small[1] - small[0])
    assert radius / np.linalg.norm(eye) == pytest.approx(np.tan(np.radians(preview.CAMERA_FOV_DEG) / 2))


def camera_of(page: Path) -> tuple[np.ndarray, np.ndarray]:
    """(scene shift (3,), camera position in the robot's base frame (3,)) recorded in a page."""
    commands = scene_commands(page.read_text(encoding="utf-8"))
    shift = [c for c in commands if c["type"] == "set_transform" and c["path"] == "/meshcat"]
    eye = [
        c
        for c in commands
        if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"
    ]
    assert len(shift) == 1 and len(eye) == 1
    x, z, minus_y = eye[0]["value"]  # three.js axes
    return np.array(shift[0]["matrix"]).reshape(4, 4).T[:3, 3], np.array([x, -minus_y, z])


def test_camera_is_fitted_to_each_robot_and_scene(page, content, tmp_path):
    panda = make_panda_content()
    panda_page = preview.write_html(panda, tmp_path / "panda.html")
    shifts, eyes = {}, {}
    for name, (pg, c) in {"baxter": (page, content), "panda": (panda_page, panda)}.items():
        shifts[name], eyes[name] = camera_of(pg)
        # the scene is moved so that the centre of its bounding box is where the camera orbits
        points = scene_points(c, RobotView(c, preview.DEFAULT_MAX_TRIANGLES))
        assert np.allclose(shifts[name], -preview.camera_view(points)[0])
        assert np.all(points.min(0) <= c.hand_path.min(0)) and np.all(points.max(0) >= c.hand_path.max(0))
    # the Panda's scene is far smaller than Baxter's: the camera comes much closer
    assert np.linalg.norm(eyes["panda"]) < 0.6 * np.linalg.norm(eyes["baxter"])
    # and the framing follows the scene: a hand path 2 m away widens the view
    far = panda.replace(hand_path=panda.hand_path + np.array([2.0, 0.0, 0.0]))
    _, far_eye = camera_of(preview.write_html(far, tmp_path / "far.html"))
    assert np.linalg.norm(far_eye) > 1.5 * np.linalg.norm(eyes["panda"])


def test_decimation_that_stops_above_its_target_is_the_same_for_lower_targets(baxter):
    """What the decimation's reuse relies on (meshes._decimated): fast_simplification's target only
    stops it early, so a run that ends above its target gives the same mesh for any lower target."""
    import fast_simplification

    from ipromp_pin.preview.meshes import mesh_arrays

    _, visual = baxter
    checked = 0
    for obj in visual.geometryObjects:
        if not isinstance(obj.geometry, coal.BVHModelBase) or obj.geometry.num_tris < 8000:
            continue
        v, f = mesh_arrays(obj.geometry)
        v, f = (v * obj.meshScale).astype(np.float32), f.astype(np.int32)
        target = len(f) // 5
        first = fast_simplification.simplify(v, f, target_count=target)
        if len(first[1]) <= target:
            continue
        lower = fast_simplification.simplify(v, f, target_count=target // 2)
        assert np.array_equal(first[0], lower[0]) and np.array_equal(first[1], lower[1])
        checked += 1
        if checked == 1:
            break
    assert checked >= 1


def test_simplify_visual_model_keeps_objects_and_meets_budget(baxter):
    _, visual = baxter
    simple = preview.simplify_visual_model(visual)  # default budget: shares the page's cached meshes
    assert simple.ngeoms == visual.ngeoms
    assert preview.count_triangles(visual) > 300_000
    assert preview.count_triangles(simple) <= 1.1 * preview.DEFAULT_MAX_TRIANGLES
    meshes = [g for g in simple.geometryObjects if isinstance(g.geometry, coal.BVHModelBase)]
    assert len(meshes) > 20 and all(g.meshPath == "" for g in meshes)
    assert visual.geometryObjects[2].meshPath != ""  # the input is not modified
    with pytest.raises(DataError, match="max_triangles"):
        preview.simplify_visual_model(visual, 10)


# -- offline page ----------------------------------------------------------------------------------


def test_offline_page_is_self_contained_and_small(page):
    html = page.read_text(encoding="utf-8")
    size_mb = page.stat().st_size / 1e6
    assert 1.0 < size_mb < 10.0
    urls = set(re.findall(r"https?://[^\s\"'<>)]*", html))
    assert urls <= {"http://www.w3.org/1999/xhtml"}, urls  # an XML namespace name, never fetched
    assert not re.search(r"<script[^>]*\ssrc=", html)
    assert not re.search(r"<link[^>]*\shref=", html)
    assert "MeshCat.Viewer" in html and "viewer.connect" not in html


def test_offline_page_holds_every_scene_element(page, content):
    commands = scene_commands(page.read_text(encoding="utf-8"))
    objects = objects_by_path(commands)
    for node in (
        "human/observed",
        "human/rest",
        "human/hand",
        "human/handover",
        "prediction/mean",
        "prediction/band",
        "prediction/samples",
        "prediction/truth",
        "labels/task",
    ):
        assert f"/meshcat/{node}" in objects, node
    robot = [p for p in objects if p.startswith("/meshcat/robot/visuals/")]
    assert len(robot) >= 30
    label = objects["/meshcat/labels/task"]["object"]["textures"][0]
    assert label["type"] == "_text" and label["text"] == "handover_cup (0.82)"
    overlay = [c for c in commands if c["type"] == "ipromp_overlay"]
    assert len(overlay) == 1
    state = overlay[0]["state"]
    assert state["task"] == "handover_cup" and state["tasks"] == list(TASKS)
    assert state["posterior"] == pytest.approx([0.82, 0.13, 0.05])
    assert [c["passed"] for c in state["feasibility"]] == [True, False, True]
    assert [c["status"] for c in state["feasibility"]] == ["pass", "fail", "skip"]
    assert state["observed"] == {
        "until_s": 1.0,
        "human_duration_s": 4.0,
        "source": "recorded",
        "fraction": 0.25,
    }
    assert state["robot_duration_s"] == pytest.approx(3.0)


def test_offline_page_colours_failing_links(page):
    commands = scene_commands(page.read_text(encoding="utf-8"))
    painted = {
        c["path"].rsplit("/", 1)[1]: c["value"]
        for c in commands
        if c["type"] == "set_property" and c["property"] == "color"
    }
    assert painted["left_lower_forearm_0"] == pytest.approx([1.0, 0.0, 0.0, 1.0])  # in collision
    assert painted["left_lower_elbow_0"] == pytest.approx(
        [1.0, 0.55, 0.0, 1.0]
    )  # moved by left_e1, near limit
    assert set(painted) == {"left_lower_forearm_0", "left_lower_elbow_0"}
    objects = objects_by_path(commands)
    darkred = objects["/meshcat/robot/visuals/left_upper_shoulder_0"]["object"]["materials"][0]["color"]
    assert darkred == int(0.5 * 255) * 65536 + int(0.1 * 255) * 257  # the description's colour


def test_offline_page_animates_the_arm_in_real_time(page, content):
    commands = scene_commands(page.read_text(encoding="utf-8"))
    animations = [c for c in commands if c["type"] == "set_animation"]
    assert len(animations) == 1
    clips = {a["path"]: a["clip"] for a in animations[0]["animations"]}
    wrist = clips["/meshcat/robot/visuals/left_wrist_0"]
    assert wrist["fps"] == 30
    times = [k["time"] for k in wrist["tracks"][0]["keys"]]
    # one clock (the human's): the animation lasts until the later of the robot's end and the hand's
    assert times[0] == 0 and times[-1] / wrist["fps"] == pytest.approx(4.0, abs=1 / 30)
    positions = np.array([k["value"] for k in wrist["tracks"][0]["keys"]])
    assert np.linalg.norm(positions[-1] - positions[0]) > 0.1  # the wrist moves
    assert "/meshcat/human/hand" in clips
    # the hand marker plays the human's motion from its start, on the same clock as the robot
    hand = np.array([k["value"] for k in clips["/meshcat/human/hand"]["tracks"][0]["keys"]])
    assert hand[0] == pytest.approx(content.hand_path[0])
    assert hand[-1] == pytest.approx(content.hand_path[-1])
    # Links that do not move (torso, right arm) carry no animation track.
    assert "/meshcat/robot/visuals/torso_0" not in clips
    assert "/meshcat/robot/visuals/right_wrist_0" not in clips


def test_minimal_content_without_optional_parts(tmp_path):
    model, collision = load_baxter(pin.GeometryType.COLLISION)
    content = preview.PreviewContent(
        model=model,
        visual_model=None,
        collision_model=collision,
        t_s=[0.0, 1.0],
        q=np.zeros((2, 7)),
        joint_names=ARM,
    )
    page = preview.write_html(content, tmp_path / "minimal.html")
    objects = objects_by_path(scene_commands(page.read_text(encoding="utf-8")))
    assert not any(p.startswith("/meshcat/human") or p.startswith("/meshcat/prediction") for p in objects)
    assert sum(p.startswith("/meshcat/robot/visuals/") for p in objects) == collision.ngeoms
    assert page.stat().st_size < 2e6


# -- live server -----------------------------------------------------------------------------------


def listening(port: int) -> list[tuple[str, str]]:
    """(table, local address hex) of every listening socket on ``port`` from /proc/net/tcp{,6}."""
    found = []
    for table in ("tcp", "tcp6"):
        path = Path("/proc/net") / table
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            address, port_hex = fields[1].split(":")
            if int(port_hex, 16) == port and fields[3] == "0A":  # 0A = LISTEN
                found.append((table, address))
    return found


def test_live_rejects_a_non_loopback_host(content):
    with pytest.raises(DataError, match="loopback"):
        preview.LivePreview(content, host="192.168.1.10", port=0)


def test_live_preview_listens_on_loopback_only_and_streams_updates(content):
    live = preview.LivePreview(content, port=0)
    try:
        assert live.url == f"http://127.0.0.1:{live.port}/"
        sockets = listening(live.port)
        assert sockets == [("tcp", "0100007F")], sockets  # 127.0.0.1 only, no IPv6 / wildcard socket
        with urllib.request.urlopen(live.url, timeout=10) as response:
            page = response.read().decode("utf-8")
        assert "MeshCat.Viewer" in page and "/ws" in page

        async def session() -> tuple[list[dict], dict]:
            import tornado.websocket

            ws = await tornado.websocket.websocket_connect(f"ws://127.0.0.1:{live.port}/ws")
            received = []
            while True:
                message = umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 20))
                received.append(message)
                if message["type"] == "ipromp_synced":
                    break
            live.update_posterior(np.array([0.1, 0.7, 0.2]))
            while True:
                message = umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 20))
                if message["type"] == "ipromp_overlay":
                    ws.close()
                    return received, message["state"]

        received, state = asyncio.run(session())
        assert received[-1]["count"] == len(received) - 1
        assert any(m.get("path") == "/meshcat/robot/visuals/left_wrist_0" for m in received)
        assert state["task"] == "handover_rod" and state["posterior"] == pytest.approx([0.1, 0.7, 0.2])
        assert live.content.task == "handover_rod"

        live.update_observation(2.0)
        assert live.content.hand_observed_count() == int(np.sum(content.hand_t_s <= 2.0))
        live.update_feasibility([("self-collision", True, "")], near_limit_joints=["left_w1"])
        assert live.content.collision_links == ()
        painted = {}
        for data in live.commands():
            message = umsgpack.unpackb(data)
            if message["type"] == "set_property" and message["property"] == "color":
                painted[message["path"].rsplit("/", 1)[1]] = message["value"]
        assert painted["left_lower_elbow_0"] == pytest.approx([0.5, 0.1, 0.1, 1.0])  # restored
        assert painted["left_lower_forearm_0"] == pytest.approx([1.0, 0.55, 0.0, 1.0])  # moved by left_w1
        assert "left_wrist_0" not in painted
    finally:
        live.close()
    assert not live.running
    assert listening(live.port) == []
    with pytest.raises(OSError), socket.create_connection(("127.0.0.1", live.port), timeout=2):
        pass
    live.close()  # idempotent
