"""The body model (ipromp_pin.human.body): capsules between tracked frames, occlusions inflated at
the human speed (bridged between reliable samples, held after the last one), the planner's view
``until`` the observation end, and the assumed human of recordings without a skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.human import BODY_PARTS, SKELETON_PREFIX, HumanMotion
from ipromp_pin.human.body import ASSUMED_POSE_M
from ipromp_pin.robot.human_settings import HumanPlacement, HumanSettings

RATE = 50.0


LIFT = np.array([0.0, 0.0, 1.0])
"""The skeleton stands 1 m above the base frame's origin (a frame at exactly (0, 0, 0) is missing)."""


def _skeleton_demo(n: int = 100, gap: tuple[int, int] | None = None, frame: str = "/head_1") -> Demo:
    """A demo whose tracked skeleton has the assumed pose (torso at :data:`LIFT`, facing -x) and moves
    along +x at 0.5 m/s; samples ``gap`` of ``frame`` are missing."""
    t = np.arange(n) / RATE
    extras = {}
    for f, off in ASSUMED_POSE_M.items():
        p = np.tile(np.array([-off[0], off[1], off[2]]) + LIFT, (n, 1))
        p[:, 0] += 0.5 * t
        if f == frame and gap is not None:
            p[gap[0] : gap[1]] = np.nan
        extras[SKELETON_PREFIX + f] = p
    groups = {"emg": np.zeros((n, 8))}
    names = {"emg": tuple(f"ch{i}" for i in range(8))}
    return Demo("task", "d0", "demo.csv", t, groups, names, extras=extras)


def test_parts_are_capsules_between_their_frames_with_regions():
    h = HumanMotion.from_demo(_skeleton_demo())
    assert h is not None and not h.assumed and h.label == "tracked"
    names = list(h.part_names)
    assert {"head", "chest", "left_hand", "left_forearm", "pelvis", "left_thigh"} <= set(names)
    assert dict(zip(names, h.regions, strict=True))["left_hand"] == "hand"
    a, b, r = h.capsules_at(0.0)
    k = names.index("left_upper_arm")
    off_s, off_e = ASSUMED_POSE_M["/left_shoulder_1"], ASSUMED_POSE_M["/left_elbow_1"]
    np.testing.assert_allclose(a[k], np.array([-off_s[0], off_s[1], off_s[2]]) + LIFT)
    np.testing.assert_allclose(b[k], np.array([-off_e[0], off_e[1], off_e[2]]) + LIFT)
    head = names.index("head")
    np.testing.assert_array_equal(a[head], b[head])  # a sphere
    np.testing.assert_allclose(r, [p.radius_m for p in BODY_PARTS])
    # the head moves at 0.5 m/s along +x: interpolated between samples
    a1, _, _ = h.capsules_at(1.01)
    assert a1[head][0] == pytest.approx(-ASSUMED_POSE_M["/head_1"][0] + 0.505)


def test_an_occluded_frame_is_held_and_its_capsule_inflated_at_the_human_speed():
    gap = (40, 60)  # t = 0.8 .. 1.18 s missing, reliable again at 1.2 s
    h = HumanMotion.from_demo(_skeleton_demo(gap=gap), HumanSettings(speed_m_s=1.0, max_inflation_m=1.0))
    head = list(h.part_names).index("head")
    _, _, r_ok = h.capsules_at(0.5)
    assert r_ok[head] == pytest.approx(0.11)
    # inside the gap, bridged between the reliable samples at 0.78 s and 1.2 s
    _, _, r_mid = h.capsules_at(0.9)
    assert r_mid[head] == pytest.approx(0.11 + 2 * 1.0 * (0.9 - 0.78))
    a_mid, _, _ = h.capsules_at(0.9)
    assert a_mid[head][0] == pytest.approx(-0.04 + 0.45, abs=1e-9)  # linear between the two ends
    # the planner at t = 0.9 s has not seen the head since 0.78 s: held there, growing since
    seen = h.until(0.9)
    a_p, _, r_p = seen.capsules_at(1.0)
    assert a_p[head][0] == pytest.approx(-0.04 + 0.5 * 0.78)
    assert r_p[head] == pytest.approx(0.11 + 1.0 * (1.0 - 0.78))
    # the other parts are known up to 0.9 s and grow after it; the cap holds
    neck = list(h.part_names).index("chest")
    assert seen.capsules_at(1.0)[2][neck] == pytest.approx(0.17 + 0.1)
    assert seen.capsules_at(5.0)[2][neck] == pytest.approx(0.17 + 1.0)
    assert seen.positions_m is h.positions_m  # the same arrays, not a copy


def test_inflation_is_capped_and_never_drops_a_frame():
    h = HumanMotion.from_demo(_skeleton_demo(gap=(10, 100)), HumanSettings(max_inflation_m=0.15))
    head = list(h.part_names).index("head")
    _, _, r = h.capsules(np.array([0.0, 0.5, 1.9]))
    assert r[0, head] == pytest.approx(0.11) and r[2, head] == pytest.approx(0.11 + 0.15)
    assert np.all(np.isfinite(h.capsules(np.linspace(0, 3, 31))[0]))


def test_a_frame_missing_at_the_first_sample_is_held_finite_after_the_planners_horizon():
    # The head is occluded for the first 10 samples, then tracked. Past the planner's horizon its
    # position is held: a NaN at sample 0 must not leak into the held position (it once did, and
    # the planner then saw no head at all after its last observation).
    h = HumanMotion.from_demo(_skeleton_demo(gap=(0, 10)), HumanSettings(speed_m_s=1.0, max_inflation_m=1.0))
    head = list(h.part_names).index("head")
    seen = h.until(1.0)
    a, b, r = seen.capsules(np.array([0.5, 1.0, 1.05, 1.5]))
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(r))
    x_obs = -ASSUMED_POSE_M["/head_1"][0] + 0.5 * 1.0
    np.testing.assert_allclose(a[1:, head, 0], x_obs, atol=1e-9)  # held at the last observation
    np.testing.assert_allclose(r[1:, head], 0.11 + np.array([0.0, 0.05, 0.5]), atol=1e-9)


def test_a_demo_without_a_skeleton_has_no_tracked_human_and_the_assumed_one_stands_in():
    demo = _skeleton_demo()
    bare = Demo("task", "d1", "bare.csv", demo.t, demo.groups, demo.channel_names)
    assert HumanMotion.from_demo(bare) is None
    placement = HumanPlacement(np.array([1.0, 0.0, 0.0]), 180.0)
    h = HumanMotion.assumed_human(HumanSettings(placement=placement))
    assert h.assumed and h.label == "assumed"
    a, _, _ = h.capsules_at(12.0)  # standing still, no growth
    names = list(h.part_names)
    np.testing.assert_allclose(a[names.index("head")], [1.0 - 0.04, 0.0, 0.35], atol=1e-12)
    assert h.capsules_at(12.0)[2][names.index("head")] == pytest.approx(0.11)
    # facing +y instead: the human's forward axis is +y
    turned = HumanMotion.assumed_human(HumanSettings(placement=HumanPlacement(np.zeros(3), 90.0)))
    np.testing.assert_allclose(turned.capsules_at(0.0)[0][names.index("head")], [0.0, 0.04, 0.35], atol=1e-12)
    # the handing hand follows a given path
    hand = np.tile([0.8, 0.1, 0.3], (demo.n_samples, 1))
    moving = HumanMotion.assumed_human(HumanSettings(placement=placement), demo.t, hand)
    np.testing.assert_allclose(moving.capsules_at(1.0)[0][names.index("left_hand")], [0.8, 0.1, 0.3])


def test_a_body_frame_never_tracked_is_an_error_naming_the_demo_and_frame():
    demo = _skeleton_demo(gap=(0, 100))
    with pytest.raises(DataError, match=r"demo\.csv.*/head_1.*never reliably tracked"):
        HumanMotion.from_demo(demo)
    with pytest.raises(DataError, match="unknown body part"):
        HumanMotion.from_demo(_skeleton_demo(), HumanSettings(radii_m={"tail": 0.1}))


def test_the_held_ends_kept_per_object_equal_the_recomputed_ones_and_follow_the_horizon():
    # the checks of one re-plan place the same (until) human at several motions: the held ends are
    # computed once per object and horizon; a copy with another horizon computes its own
    h = HumanMotion.from_demo(_skeleton_demo(gap=(40, 60)), HumanSettings(speed_m_s=1.0, max_inflation_m=1.0))
    seen = h.until(0.9)
    t_short, t_long = 0.9 + 0.01 * np.arange(30), 0.9 + 0.01 * np.arange(80)
    first = seen.capsules(t_short)
    assert "_held_cache" in seen.__dict__
    again = seen.capsules(t_long)  # from the kept ends
    fresh = h.until(0.9).capsules(t_long)  # a new object: computed
    for x, y, z in zip(first, again, fresh, strict=True):
        np.testing.assert_array_equal(y, z)
        np.testing.assert_array_equal(x, y[:30])
    later = seen.until(0.5)  # a shallow copy carrying the kept ends of horizon 0.9
    t_late = 0.5 + 0.01 * np.arange(50)
    for x, y in zip(later.capsules(t_late), h.until(0.5).capsules(t_late), strict=True):
        np.testing.assert_array_equal(x, y)
    a_late = later.capsules(np.array([1.0]))[0][0, list(h.part_names).index("head")]
    a_held = seen.capsules(np.array([1.0]))[0][0, list(h.part_names).index("head")]
    assert a_late[0] != a_held[0]  # the head is held where it was at 0.5 s, not at 0.78 s
