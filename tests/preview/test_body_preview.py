"""The human body and its separation in the previews: capsules moving with the recording, the closest
robot-body pair as a rod coloured by its state, and the panel's separation data on the animation's
time base (offline page, live page and the replay timeline)."""

from __future__ import annotations

import numpy as np
import pytest
from test_preview import load_baxter, make_content, objects_by_path, scene_commands

from ipromp_pin import preview
from ipromp_pin.exceptions import DataError
from ipromp_pin.preview.body import SEPARATION_STATES, BodyTrack, SeparationTrack
from ipromp_pin.preview.body_scene import capsule_transforms, separation_panel
from ipromp_pin.preview.scene import overlay_state
from ipromp_pin.preview.timeline import TimelineEvent, render_timeline_html

PARTS = ("head", "torso", "right_upper_arm", "right_forearm", "right_hand")


def point_capsule(p: np.ndarray, a: np.ndarray, b: np.ndarray, r: float) -> tuple[float, np.ndarray]:
    """(distance [m], the capsule's closest point) of point ``p`` to the capsule a-b of radius ``r``."""
    d = b - a
    s = 0.0 if not d.any() else float(np.clip((p - a) @ d / (d @ d), 0.0, 1.0))
    c = a + s * d
    gap = p - c
    n = float(np.linalg.norm(gap))
    return max(n - r, 0.0), c + (gap / n if n > 0 else gap) * min(r, n)


def make_body(content: preview.PreviewContent, assumed: bool = False) -> BodyTrack:
    """A standing human facing the robot whose right hand follows the content's hand path."""
    t = content.hand_t_s
    hand = content.hand_path
    chest = np.array([1.25, 0.6, -0.1])
    shoulder = chest + np.array([-0.05, 0.2, 0.2])
    n = t.size
    elbow = shoulder + 0.5 * (hand - shoulder) + np.array([0.0, 0.0, -0.12])
    a = np.stack(
        [
            np.repeat((chest + [0, 0, 0.55])[None], n, 0),
            np.repeat((chest + [0, 0, -0.35])[None], n, 0),
            np.repeat(shoulder[None], n, 0),
            elbow,
            hand,
        ],
        1,
    )
    b = a.copy()
    b[:, 1] = chest + [0, 0, 0.3]
    b[:, 2] = elbow
    b[:, 3] = hand
    radius = np.tile([0.11, 0.16, 0.05, 0.04, 0.05], (n, 1))
    radius[n // 2 :, 3] += 0.03  # an occluded forearm, inflated
    return BodyTrack(t, a, b, radius, PARTS, assumed)


def make_separation(content: preview.PreviewContent, body: BodyTrack) -> SeparationTrack:
    """The gripper path's (``ee_mean``) separation from ``body`` at the robot's samples, on the human's
    clock (the robot starts at ``observed_until_s``); S_p 0.3 m, speed ratio from the gripper speed."""
    t_h = content.t_s + content.observed_until_s
    ee = content.ee_mean
    a, b, r = body.at(t_h)
    speed = np.r_[0.0, np.linalg.norm(np.diff(ee, axis=0), axis=1) / np.diff(content.t_s)]
    dist, points, parts, states = [], [], [], []
    for i in range(t_h.size):
        pairs = [point_capsule(ee[i], a[i, k], b[i, k], float(r[i, k])) for k in range(body.n_parts)]
        k = int(np.argmin([d for d, _ in pairs]))
        dist.append(pairs[k][0])
        points.append(pairs[k][1])
        parts.append(PARTS[k])
        ratio = speed[i] / 0.25
        inside = "violation" if ratio > 1 else ("speed_limited" if ratio > 0.8 else "within_sp")
        states.append("free" if pairs[k][0] > 0.3 else inside)
    return SeparationTrack(
        t_h, np.array(dist), ee, np.array(points), states, ["left_gripper"] * t_h.size, parts,
        np.full(t_h.size, 0.3), speed / 0.25, "recorded human",
    )  # fmt: skip


@pytest.fixture(scope="module")
def baxter():
    return load_baxter()


@pytest.fixture(scope="module")
def human_content(baxter):
    base = make_content(*baxter)
    body = make_body(base)
    return base.replace(body=body, separation=make_separation(base, body))


def test_body_track_interpolates_and_holds_beyond_its_ends(human_content):
    body = human_content.body
    mid = 0.5 * (body.t_s[3] + body.t_s[4])
    a, b, r = body.at(np.array([-1.0, mid, 99.0]))
    np.testing.assert_allclose(a[0], body.a_m[0])
    np.testing.assert_allclose(a[1], 0.5 * (body.a_m[3] + body.a_m[4]))
    np.testing.assert_allclose(b[2], body.b_m[-1])
    assert r.shape == (3, len(PARTS))


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda kw: kw.update(radius_m=-kw["radius_m"]), "body.radius_m"),
        (lambda kw: kw.update(a_m=kw["a_m"][:, :2]), "body.a_m"),
        (lambda kw: kw.update(t_s=kw["t_s"][::-1]), "body.t_s"),
        (lambda kw: kw.update(part_names=()), "body.part_names"),
    ],
)
def test_body_track_rejects_bad_input(human_content, change, field):
    b = human_content.body
    kw = dict(t_s=b.t_s, a_m=b.a_m, b_m=b.b_m, radius_m=b.radius_m.copy(), part_names=b.part_names)
    change(kw)
    with pytest.raises(DataError, match=field.replace(".", r"\.")):
        BodyTrack(**kw)


def test_separation_track_rejects_unknown_states_and_lengths(human_content):
    s = human_content.separation
    args = (s.t_s, s.distance_m, s.robot_point_m, s.body_point_m)
    with pytest.raises(DataError, match="unknown state"):
        SeparationTrack(*args, ["close"] * s.t_s.size)
    with pytest.raises(DataError, match="separation.link"):
        SeparationTrack(*args, s.state, link=["x"])
    with pytest.raises(DataError, match="separation.distance_m"):
        SeparationTrack(s.t_s, -s.distance_m, s.robot_point_m, s.body_point_m, s.state)
    with pytest.raises(DataError, match="expected a BodyTrack"):
        human_content.replace(body="a body")


def test_capsule_nodes_span_the_segment():
    a, b = np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.4])
    nodes = capsule_transforms(a, b, 0.05)
    T, scale = nodes["cyl"]
    np.testing.assert_allclose(T[:3, 3], [1.0, 0.0, 0.2])
    np.testing.assert_allclose(T[:3, 1], [0.0, 0.0, 1.0], atol=1e-12)  # the unit cylinder's axis (y)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert scale == [0.05, pytest.approx(0.4), 0.05]
    np.testing.assert_allclose(nodes["b"][0][:3, 3], b)
    _, point = capsule_transforms(a, a, 0.1)["cyl"]  # a sphere: a zero-length cylinder
    assert point[1] > 0


def test_panel_separation_is_on_the_pages_one_clock(human_content):
    sep = human_content.separation
    state = overlay_state(human_content)["separation"]
    np.testing.assert_allclose(state["t_s"], sep.t_s, atol=1e-3)  # the human's clock
    np.testing.assert_allclose(state["distance_m"], sep.distance_m, atol=1e-4)
    assert state["body_part"] == list(sep.body_part) and state["judged"] == [True] * sep.t_s.size
    assert "min" not in state  # the panel states the report's figures, no minimum of its own
    assert sum(state["counts"].values()) == sep.t_s.size and set(state["counts"]) == set(SEPARATION_STATES)
    assert state["counts"]["free"] > 0 and state["counts"]["free"] < sep.t_s.size
    legend = [item["label"] for item in overlay_state(human_content)["legend"]]
    assert "human body (tracked)" in legend and "closest robot-body pair: violation" in legend
    assumed = human_content.replace(body=make_body(human_content, assumed=True), separation=None)
    state = overlay_state(assumed)
    assert state["separation"] is None and "human body (assumed, no skeleton)" in [
        x["label"] for x in state["legend"]
    ]
    assert separation_panel(sep)["t_s"][0] == pytest.approx(sep.t_s[0], abs=1e-3)


def animation_tracks(commands: list[dict]) -> dict[str, dict[str, list]]:
    """Animated path -> track name -> its keys, from the last set_animation command."""
    anim = [c for c in commands if c["type"] == "set_animation"][-1]
    return {a["path"]: {t["name"]: t["keys"] for t in a["clip"]["tracks"]} for a in anim["animations"]}


def check_body_scene(commands: list[dict], content: preview.PreviewContent, offset: float) -> None:
    objects = objects_by_path(commands)
    for k in range(len(PARTS)):
        for end in ("cyl", "a", "b"):
            assert f"/meshcat/human/body/{k}/{end}" in objects
    for state in SEPARATION_STATES:
        assert f"/meshcat/human/closest/{state}" in objects
    tracks = animation_tracks(commands)
    # the forearm (part 3) moves and is inflated halfway through: its capsule's scale follows
    forearm = tracks["/meshcat/human/body/3/cyl"]
    radii = [key["value"][0] for key in forearm[".scale"]]
    assert min(radii) == pytest.approx(0.04) and max(radii) == pytest.approx(0.07)
    fps = 30.0
    times = [key["time"] / fps for key in forearm[".position"]]
    a, b, _ = content.body.at(np.array(times) + offset)
    got = np.array([key["value"] for key in forearm[".position"]])
    np.testing.assert_allclose(got, (a[:, 3] + b[:, 3]) / 2, atol=1e-6)
    # the rod of each sample's state is the one shown
    sep = content.separation
    shown = {s: tracks[f"/meshcat/human/closest/{s}"].get(".visible", []) for s in SEPARATION_STATES}
    for state, keys in shown.items():
        for key in keys:
            t = key["time"] / fps + offset
            i = int(np.clip(np.searchsorted(sep.t_s, t + 1e-9) - 1, 0, sep.t_s.size - 1))
            assert key["value"] == (sep.state[i] == state)
    assert any(any(k["value"] for k in keys) for state, keys in shown.items() if state != "free")


def test_offline_page_draws_the_moving_body_and_the_closest_pair(human_content, tmp_path):
    path = preview.write_html(human_content, tmp_path / "body.html")
    commands = scene_commands(path.read_text())
    check_body_scene(commands, human_content, 0.0)  # one clock: the human's
    assert "/meshcat/labels/closest" in objects_by_path(commands)
    assert "ipromp-separation" in path.read_text()  # the panel's script is on the page


def test_timeline_page_draws_the_body_on_the_human_clock(human_content):
    events = [TimelineEvent(t_s=1.0, observed_until_s=1.0, task="handover_cup", committed=True)]
    # the timeline's robot trajectory is on the human's clock: shift it by the observation
    content = human_content.replace(t_s=human_content.t_s + 1.0, observed_until_s=None)
    html = render_timeline_html(content, events, motion_s=4.0)
    check_body_scene(scene_commands(html), content, 0.0)


def test_content_without_body_draws_none(baxter, tmp_path):
    path = preview.write_html(make_content(*baxter), tmp_path / "plain.html")
    objects = objects_by_path(scene_commands(path.read_text()))
    assert not any(
        p.startswith("/meshcat/human/body") or p.startswith("/meshcat/human/closest") for p in objects
    )


def test_separation_keeps_unknown_values_as_null(human_content):
    s = human_content.separation
    sp = s.protective_distance_m.copy()
    sp[:3] = np.nan
    track = SeparationTrack(
        s.t_s, s.distance_m, s.robot_point_m, s.body_point_m, s.state, protective_distance_m=sp
    )
    panel = separation_panel(track)
    assert panel["protective_distance_m"][:3] == [None] * 3 and panel["protective_distance_m"][3] == 0.3
    sp[4] = np.inf
    with pytest.raises(DataError, match="protective_distance_m"):
        SeparationTrack(
            s.t_s, s.distance_m, s.robot_point_m, s.body_point_m, s.state, protective_distance_m=sp
        )
