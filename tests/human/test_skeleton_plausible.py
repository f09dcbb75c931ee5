"""Impossible tracked skeletons (issue of 2026-12-04, round 3): a frame at exactly (0, 0, 0) is a
missing sample (the recorders' publishing bug), never a position; a skeleton whose segments are
outside anthropometric bounds is refused, a few impossible samples become gaps; the real recordings
of handover_20171128 are still read."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.human import BODY_PARTS, SKELETON_PREFIX, HumanMotion
from ipromp_pin.human.body import ASSUMED_POSE_M
from ipromp_pin.human.skeleton import SEGMENT_RANGES
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.multimodal import read_demo
from ipromp_pin.robot.human_settings import HumanSettings

RATE = 50.0
STAND = np.array([1.27, -0.26, 0.15])  # where the tracked partner stands, in the robot's base frame


def _demo(n: int = 100, edit=None) -> Demo:
    """A tracked human standing still at the assumed pose (facing -x) at :data:`STAND`; ``edit``
    (frame -> positions (n, 3)) may change the positions."""
    t = np.arange(n) / RATE
    extras = {}
    for f, off in ASSUMED_POSE_M.items():
        p = np.tile(STAND + np.array([-off[0], off[1], off[2]]), (n, 1))
        if edit is not None:
            edit(f, p)
        extras[SKELETON_PREFIX + f] = p
    names = {"emg": tuple(f"ch{i}" for i in range(8))}
    return Demo("task", "d0", "demo.csv", t, {"emg": np.zeros((n, 8))}, names, extras=extras)


def _head_at(value, rows=slice(None)):
    def edit(frame, p):
        if frame == "/head_1":
            p[rows] = value

    return edit


def test_a_frame_at_the_origin_is_a_missing_sample_not_a_position():
    h = HumanMotion.from_demo(_demo(edit=_head_at(0.0, slice(40, 50))), HumanSettings())
    j = h.frames.index("/head_1")
    assert np.all(np.isnan(h.positions_m[40:50, j])) and np.all(np.isfinite(h.positions_m[:40, j]))
    a, _, r = h.capsules_at(45 / RATE)
    head = list(h.part_names).index("head")
    assert np.linalg.norm(a[head] - h.positions_m[39, j]) < 1e-9  # bridged, not at the origin
    assert r[head] > 0.11  # and inflated over the gap


def test_a_frame_always_at_the_origin_is_never_tracked():
    with pytest.raises(DataError, match="never reliably tracked"):
        HumanMotion.from_demo(_demo(edit=_head_at(0.0)), HumanSettings())


def test_an_impossible_skeleton_is_refused_naming_the_segment_range_and_source():
    far = STAND + np.array([0.0, 0.0, 1.36])  # the head 1.36 m from the torso, ~1.2 m from the neck
    with pytest.raises(DataError) as exc:
        HumanMotion.from_demo(_demo(edit=_head_at(far)), HumanSettings())
    msg = str(exc.value)
    assert msg.startswith("demo.csv: field 'neck': ") and "plausible range" in msg, msg
    assert SEGMENT_RANGES["neck"].source in msg


def test_a_few_impossible_samples_become_gaps():
    far = STAND + np.array([0.0, 0.0, 1.36])
    h = HumanMotion.from_demo(_demo(edit=_head_at(far, slice(60, 63))), HumanSettings())
    j = h.frames.index("/head_1")
    assert np.all(np.isnan(h.positions_m[60:63, j])) and np.all(np.isfinite(h.positions_m[:60, j]))


def test_every_capsule_part_has_a_range_that_holds_the_assumed_pose():
    def end(e: str) -> np.ndarray:
        return np.mean([np.array(ASSUMED_POSE_M[f]) for f in e.split("+")], axis=0)

    capsules = [p for p in BODY_PARTS if p.b is not None]
    assert set(SEGMENT_RANGES) == {p.name for p in capsules}
    for part in capsules:
        length = float(np.linalg.norm(end(part.a) - end(part.b)))
        assert SEGMENT_RANGES[part.name].contains(length), (part.name, length)


def _copy_one(src: Path, dst: Path) -> Path:
    stamp = sorted((src / "pincer" / "csv").iterdir())[0]
    out = dst / "pincer" / "csv" / stamp.name
    out.mkdir(parents=True)
    shutil.copy(stamp / "multiModal_states.csv", out / "multiModal_states.csv")
    return out / "multiModal_states.csv"


@pytest.mark.realdata
def test_a_recorded_head_at_the_origin_with_a_rotation_is_missing(tmp_path, handover2017_dir):
    path = _copy_one(handover2017_dir, tmp_path / "mm")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    changed = []
    for r, row in enumerate(rows[1:], start=1):
        for k in range(16):
            col = f"field.tf_of_interest.transforms{k}."
            if (
                col + "child_frame_id" in head
                and row[head.index(col + "child_frame_id")].strip() == "/head_1"
            ):
                if 100 <= r < 110:
                    for a in "xyz":
                        row[head.index(col + f"transform.translation.{a}")] = "0.0"
                    changed.append(r)
    assert changed
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    demo = read_demo(path)
    pos = demo.extras[SKELETON_PREFIX + "/head_1"]
    finite = np.all(np.isfinite(pos), axis=1)
    assert not np.any(np.linalg.norm(pos[finite], axis=1) < 0.3)  # never near the base frame's origin
    assert not finite.all()


@pytest.mark.realdata
def test_the_real_recordings_still_become_bodies(handover2017_dir):
    ds = load_dataset(handover2017_dir)
    gaps = total = 0
    for demo in ds.all_demos():
        h = HumanMotion.from_demo(demo, HumanSettings())
        assert h is not None and not h.assumed
        recorded = np.stack([demo.extras[SKELETON_PREFIX + f] for f in h.frames], axis=1)
        ok = np.all(np.isfinite(recorded), axis=2)
        gaps += int(np.sum(ok & ~np.all(np.isfinite(h.positions_m), axis=2)))
        total += int(ok.sum())
    assert gaps / total < 0.005  # the impossible samples made gaps: under half a percent
