"""Tests of the demo readers (real recordings where present, tmp copies for bad input): native CSV
columns matched by name, unreadable or unknown task folders refused."""

from __future__ import annotations

import csv
import dataclasses
import datetime
import os
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.data import ROBOT
from ipromp_pin.exceptions import DataError
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import (
    BAXTER_LEFT_JOINTS,
    chen2017,
    detect_format,
    load_dataset,
    multimodal,
    read_demo,
    rosbag,
    write_dataset,
    write_demo,
)
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.signals.preprocess import EnvelopeFilter, quaternion_continuity

TASKS = ("aluminum_hold", "spanner_handover", "tape_hold")
STAMP = "2017-07-11-15-45-25"  # a tape_hold demo
SUFFIXES = tuple(chen2017.TOPIC_SUFFIXES.values())


# ----------------------------------------------------------------------------------------- helpers
def copy_demo(chen2017_dir: Path, dst: Path, task: str = "tape_hold", stamp: str = STAMP) -> Path:
    """Copy one chen2017 demo's CSVs to dst/<task>/csv; returns the demo prefix."""
    out = dst / task / "csv"
    out.mkdir(parents=True, exist_ok=True)
    for s in SUFFIXES:
        shutil.copy(chen2017_dir / task / "csv" / f"{stamp}-{s}.csv", out)
    return out / stamp


def edit_csv(path: Path, fn) -> None:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    rows = fn(rows)
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def shift_time_text(s: str, dt_s: float) -> str:
    d = datetime.datetime.strptime(s, "%Y/%m/%d/%H:%M:%S.%f") + datetime.timedelta(seconds=dt_s)
    return d.strftime("%Y/%m/%d/%H:%M:%S.%f")


def speed_lag(a: np.ndarray, b: np.ndarray, dt: float, max_lag_s: float) -> float:
    """Lag (in [s]) maximising the cross-correlation of a(t + lag) with b(t)."""
    a = np.nan_to_num(a - np.nanmean(a))
    b = np.nan_to_num(b - np.nanmean(b))
    n = a.size
    m = min(int(max_lag_s / dt), n - 10)
    lags = np.arange(-m, m + 1)
    c = [np.dot(a[max(0, k) : n + min(0, k)], b[max(0, -k) : n - max(0, k)]) for k in lags]
    return float(lags[int(np.argmax(c))] * dt)


def joint_speed(q: np.ndarray, dt: float) -> np.ndarray:
    return np.linalg.norm(np.gradient(q, dt, axis=0), axis=1)


def orientation_speed(quat: np.ndarray, dt: float) -> np.ndarray:
    return 2.0 * np.linalg.norm(np.gradient(quaternion_continuity(quat), dt, axis=0), axis=1)


# ------------------------------------------------------------------------------------ chen2017 CSV
def test_chen2017_demo_groups_and_joint_mapping(chen2017_dir):
    prefix = chen2017_dir / "tape_hold" / "csv" / STAMP
    demo = read_demo(prefix)
    assert demo.task == "tape_hold" and demo.name == STAMP
    assert demo.channel_names["orientation"] == ("qw", "qx", "qy", "qz")
    assert demo.channel_names["emg"] == tuple(f"emg{i}" for i in range(8))
    assert demo.channel_names[ROBOT] == BAXTER_LEFT_JOINTS
    assert demo.t[0] == 0.0 and np.allclose(np.diff(demo.t), 0.02)
    assert 2.4 < demo.duration_s < 2.7  # the bag spans 2.58 s
    np.testing.assert_allclose(np.linalg.norm(demo.groups["orientation"], axis=1), 1.0, atol=1e-9)
    assert np.all(np.einsum("ij,ij->i", demo.groups["orientation"][1:], demo.groups["orientation"][:-1]) > 0)
    assert np.all(demo.groups["emg"] >= 0)
    assert demo.extras["endpoint_pose"].shape == (demo.n_samples, 7)

    # The first arm message, mapped by name: the file lists names alphabetically.
    with open(f"{prefix}-robot-joint_states.csv") as fh:
        rows = list(csv.DictReader(fh))
    arm = [r for r in rows if "left_s0" in r[".name"]]
    names = [n.strip(" '") for n in arm[0][".name"][1:-1].split(",")]
    raw_q = [float(x) for x in arm[0][".position"][1:-1].split(",")]
    first = {n: raw_q[i] for i, n in enumerate(names)}
    np.testing.assert_allclose(demo.groups[ROBOT][0], [first[j] for j in BAXTER_LEFT_JOINTS], atol=0.01)
    # Gripper-only messages (one name) are dropped: the trajectory has no spikes.
    assert any(r[".name"].count(",") == 0 for r in rows)
    assert np.max(np.abs(np.diff(demo.groups[ROBOT], axis=0))) < 0.05
    # Another joint order maps by name too.
    rev = read_demo(prefix, robot_joints=BAXTER_LEFT_JOINTS[::-1])
    np.testing.assert_allclose(rev.groups[ROBOT], demo.groups[ROBOT][:, ::-1])


def test_chen2017_orientation_w_is_quat0(chen2017_dir):
    """With w = quat0, the quaternion predicts gravity along the accelerometer."""
    demo = read_demo(chen2017_dir / "aluminum_hold" / "csv" / "2017-07-11-15-17-23")
    w, x, y, z = demo.groups["orientation"].T
    # Third row of the rotation matrix = world z (up) in the sensor frame.
    up = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
    acc = demo.groups["acc"] / np.linalg.norm(demo.groups["acc"], axis=1, keepdims=True)
    assert np.mean(np.abs(np.sum(up * acc, axis=1))) > 0.98
    assert 0.9 < np.median(np.linalg.norm(demo.groups["acc"], axis=1)) < 1.1  # [g]


def test_chen2017_clock_offsets_are_estimated_not_assumed(chen2017_dir, tmp_path):
    prefix = chen2017_dir / "tape_hold" / "csv" / STAMP
    offsets = chen2017.clock_offsets(prefix)
    assert offsets["robot"] == pytest.approx(3.95, abs=0.05)
    assert offsets["endpoint"] == pytest.approx(3.95, abs=0.05)
    assert abs(offsets["emg"]) < 0.01 and abs(offsets["imu"]) < 0.01
    # Move the robot's clock 10 s further ahead: same demo, larger offset.
    copy = copy_demo(chen2017_dir, tmp_path)
    for s in ("robot-joint_states", "robot-limb-left-endpoint_state"):

        def shift(rows):
            i = rows[0].index(".header.stamp.secs")
            for r in rows[1:]:
                r[i] = str(int(r[i]) + 10)
            return rows

        edit_csv(Path(f"{copy}-{s}.csv"), shift)
    assert chen2017.clock_offsets(copy)["robot"] == pytest.approx(offsets["robot"] + 10, abs=1e-6)
    a, b = read_demo(prefix), read_demo(copy)
    assert a.n_samples == b.n_samples
    np.testing.assert_allclose(b.groups[ROBOT], a.groups[ROBOT], atol=1e-6)


def test_chen2017_robot_and_human_motion_line_up(chen2017_dir):
    """Robot joint speed and Myo rotation speed peak together after alignment, ~4 s apart on raw stamps."""
    aligned, raw_lags = [], []
    for task in TASKS:
        for prefix in chen2017.list_demos(chen2017_dir / task)[:4]:
            demo = read_demo(prefix)
            dt = demo.dt
            aligned.append(
                speed_lag(
                    joint_speed(demo.groups[ROBOT], dt),
                    orientation_speed(demo.groups["orientation"], dt),
                    dt,
                    1.5,
                )
            )
            raw = chen2017.read_raw(prefix)
            # Raw header stamps, no clock correction: both streams on a grid spanning both.
            tr, tm = raw.joints.header_s, raw.imu.header_s
            grid = np.arange(min(tr[0], tm[0]), max(tr[-1], tm[-1]), 0.02)
            q = np.column_stack(
                [np.interp(grid, tr, c, left=np.nan, right=np.nan) for c in raw.joints.values.T]
            )
            o = quaternion_continuity(raw.imu.values[:, :4])
            o = np.column_stack([np.interp(grid, tm, c, left=np.nan, right=np.nan) for c in o.T])
            raw_lags.append(speed_lag(joint_speed(q, 0.02), orientation_speed(o, 0.02), 0.02, 6.0))
            # On raw stamps the streams barely overlap at all.
            assert min(tr[-1], tm[-1]) - max(tr[0], tm[0]) < 0.25 * demo.duration_s
    assert abs(np.median(aligned)) < 0.3, aligned
    assert np.median(np.abs(aligned)) < 0.3, aligned
    assert np.median(raw_lags) > 3.0, raw_lags


def test_chen2017_emg_truncated_demo_equals_online_processing(chen2017_dir):
    prefix = chen2017_dir / "spanner_handover" / "csv" / "2017-07-11-16-06-43"
    demo = read_demo(prefix)
    raw = chen2017.read_raw(prefix)
    offs = chen2017.clock_offsets(prefix)
    starts = [
        raw.emg.header_s[0] - offs["emg"],
        raw.imu.header_s[0] - offs["imu"],
        raw.joints.header_s[0] - offs["robot"],
        raw.endpoint.header_s[0] - offs["endpoint"],
    ]
    t0 = max(starts)
    t_emg = raw.emg.header_s - offs["emg"]
    head = demo.head(0.3)
    filt = EnvelopeFilter(8, demo.dt)
    online = []
    for tk in t0 + head.t:
        # Online: the latest EMG message received by grid time tk.
        i = np.searchsorted(t_emg, tk + 1e-9, side="right") - 1
        online.append(filt.update(raw.emg.values[i]))
    np.testing.assert_allclose(head.groups["emg"], np.array(online), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(head.groups["emg"], demo.groups["emg"][: head.n_samples])


def test_load_chen2017_whole_dataset_in_config_order(chen2017_dir):
    seen = []
    ds = load_dataset(chen2017_dir, progress=lambda done, total, name: seen.append((done, total, name)))
    assert ds.tasks == list(TASKS)
    assert [len(ds.demos[t]) for t in TASKS] == [39, 30, 30]
    assert seen[-1][:2] == (99, 99) and len(seen) == 99
    for t in TASKS:
        cfg = chen2017.read_config_order(chen2017_dir / t / "csv" / f"filename_{t}.cfg")
        assert [d.name for d in ds.demos[t]] == cfg
    durations = np.array([d.duration_s for d in ds.all_demos()])
    assert durations.min() > 2.4 and durations.max() < 4.3
    assert set(ds.groups()) == {"orientation", "emg", "acc", ROBOT}


def test_chen2017_order_with_incomplete_config(chen2017_dir, tmp_path):
    stamps = [p.name for p in chen2017.list_demos(chen2017_dir / "tape_hold", "recorded")[:3]]
    for s in stamps:
        copy_demo(chen2017_dir, tmp_path, stamp=s)
    cfg = tmp_path / "tape_hold" / "csv" / "filename_tape_hold.cfg"
    cfg.write_text(f"{stamps[2]}-\n{stamps[0]}-\n2017-07-11-23-59-59-\n")
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        demos = chen2017.list_demos(tmp_path / "tape_hold")
    text = " ".join(str(x.message) for x in w)
    assert "2017-07-11-23-59-59" in text and "skipped" in text
    assert stamps[1] in text and "appended" in text
    assert [p.name for p in demos] == [stamps[2], stamps[0], stamps[1]]
    assert [p.name for p in chen2017.list_demos(tmp_path / "tape_hold", "recorded")] == stamps
    cfg.write_text("not-a-stamp\n")
    with pytest.raises(DataError, match="filename_tape_hold.cfg.*line 1"):
        chen2017.list_demos(tmp_path / "tape_hold")


# ------------------------------------------------------------------------------------ bad chen2017
def _break(rows, column, fn):
    i = rows[0].index(column)
    fn(rows, i)
    return rows


@pytest.mark.parametrize(
    ("suffix", "edit", "pattern"),
    [
        (
            "myo_raw_emg_pub",
            lambda r: [row[:8] + row[9:] for row in r],
            r"emg_pub\.csv: field '\.ch3': missing column",
        ),
        (
            "myo_raw_emg_pub",
            lambda r: _break(r, ".ch2", lambda rows, i: rows[20].__setitem__(i, "nan")),
            r"emg_pub\.csv: field 'emg/emg2': 1 NaN",
        ),
        (
            "myo_raw_emg_pub",
            lambda r: _break(r, ".ch0", lambda rows, i: rows[5].__setitem__(i, "abc")),
            r"emg_pub\.csv: field '\.ch0': line 6: not a number",
        ),
        ("myo_raw_imu_pub", lambda r: r[:1], r"imu_pub\.csv: stream is empty"),
        ("myo_raw_imu_pub", lambda r: r[:2], r"imu_pub\.csv: field 'orientation': .*at least 2"),
        (
            "myo_raw_imu_pub",
            lambda r: _break(
                r, ".quat0", lambda rows, i: [row.__setitem__(i, str(3 * int(row[i]))) for row in rows[1:]]
            ),
            r"imu_pub\.csv: field '\.quat0-3': .*norm",
        ),
        ("robot-joint_states", lambda r: r[:1], r"joint_states\.csv: stream is empty"),
        (
            "robot-joint_states",
            lambda r: _break(r, ".position", lambda rows, i: rows[1].__setitem__(i, "(0.0, 1.0)")),
            r"joint_states\.csv: field '\.position': line 2: expected a tuple of 17 numbers",
        ),
    ],
)
def test_chen2017_bad_files(chen2017_dir, tmp_path, suffix, edit, pattern):
    prefix = copy_demo(chen2017_dir, tmp_path)
    edit_csv(Path(f"{prefix}-{suffix}.csv"), edit)
    with pytest.raises(DataError, match=pattern):
        read_demo(prefix)


def test_chen2017_truncated_file_unknown_joint_and_unsynchronised(chen2017_dir, tmp_path):
    prefix = copy_demo(chen2017_dir, tmp_path)
    with pytest.raises(DataError, match=r"joint_states\.csv: field 'left_x9': unknown joint name.*left_s0"):
        read_demo(prefix, robot_joints=("left_s0", "left_x9"))
    # Unsynchronised: the EMG recorded 100 s later (header and receive time agree, so no clock fix).
    emg = Path(f"{prefix}-myo_raw_emg_pub.csv")

    def later(rows):
        i = rows[0].index(".header.stamp.secs")
        for r in rows[1:]:
            r[i] = str(int(r[i]) + 100)
            r[0] = shift_time_text(r[0], 100.0)
        return rows

    edit_csv(emg, later)
    with pytest.raises(DataError, match="do not overlap"):
        read_demo(prefix)
    # Truncated in the middle of a line.
    js = Path(f"{prefix}-robot-joint_states.csv")
    text = js.read_text()
    js.write_text(text[: len(text) // 2])
    with pytest.raises(DataError, match=r"joint_states\.csv: field 'line \d+': has \d+ fields"):
        read_demo(prefix)


# ----------------------------------------------------------------------------------------- bags
def test_bag_matches_csv(chen2017_dir):
    a = read_demo(chen2017_dir / "tape_hold" / "csv" / STAMP)
    b = read_demo(chen2017_dir / "tape_hold" / f"{STAMP}.bag")
    assert (b.task, b.name, b.n_samples) == (a.task, a.name, a.n_samples)
    for g in a.groups:
        np.testing.assert_allclose(b.groups[g], a.groups[g], atol=1e-4, rtol=1e-6)
    np.testing.assert_allclose(b.extras["endpoint_pose"], a.extras["endpoint_pose"], atol=1e-5)
    assert (
        rosbag.list_demos(chen2017_dir / "tape_hold")[0].stem
        == chen2017.list_demos(chen2017_dir / "tape_hold")[0].name
    )


def test_bad_bags(chen2017_dir, tmp_path):
    src = chen2017_dir / "tape_hold" / f"{STAMP}.bag"
    bad = tmp_path / "cut.bag"
    bad.write_bytes(src.read_bytes()[:20000])
    with pytest.raises(DataError, match=r"cut\.bag"):
        rosbag.read_demo(bad)
    with pytest.raises(DataError, match=r"field '/no/such/topic': topic missing"):
        rosbag.read_demo(src, topics={"emg": "/no/such/topic"})
    with pytest.raises(DataError, match="left_x9"):
        rosbag.read_demo(src, robot_joints=("left_x9",))


# ---------------------------------------------------------------------------------- multimodal
def _mm_file(handover2017_dir: Path) -> Path:
    return sorted((handover2017_dir / "pincer" / "csv").glob(f"*/{multimodal.FILE_NAME}"))[0]


def test_multimodal_demo(handover2017_dir):
    path = _mm_file(handover2017_dir)
    demo = read_demo(path, frames=["/left_hand_1", "/head_1"])
    assert demo.task == "pincer" and demo.name == path.parent.name
    assert set(demo.groups) == {"orientation", "emg", "acc", "/left_hand_1", "/head_1", ROBOT}
    assert demo.channel_names["/left_hand_1"] == ("x", "y", "z")
    assert np.allclose(np.diff(demo.t), 0.02) and 3.5 < demo.duration_s < 4.5
    np.testing.assert_allclose(np.linalg.norm(demo.groups["orientation"], axis=1), 1.0, atol=1e-9)
    hand = demo.extras["hand_position"]
    assert np.all(np.isfinite(hand))
    # The human hand (the left one in this session) ends at the robot's gripper.
    ep = demo.extras["endpoint_pose"][:, :3]
    assert np.median(np.linalg.norm(hand[-10:] - ep[-10:], axis=1)) < 0.25
    assert np.linalg.norm(hand[0] - ep[0]) > 0.5
    ok = ~demo.missing.get("/left_hand_1", np.zeros(demo.n_samples, bool))
    np.testing.assert_allclose(hand[ok], demo.groups["/left_hand_1"][ok])
    with pytest.raises(DataError, match=r"field '/nose_1': frame never tracked.*/left_hand_1"):
        read_demo(path, frames=["/nose_1"])


def test_multimodal_frames_by_child_frame_id_zero_and_jumps(handover2017_dir, tmp_path):
    path = _mm_file(handover2017_dir)
    ref = read_demo(path, frames=["/left_hand_1", "/head_1"])
    copy = tmp_path / "pincer" / "csv" / path.parent.name / multimodal.FILE_NAME
    copy.parent.mkdir(parents=True)
    shutil.copy(path, copy)

    def swap(rows):
        # Exchange the transforms holding /head_1 (K=0) and /left_hand_1 (K=5) on every other row.
        h = rows[0]
        a = [i for i, c in enumerate(h) if c.startswith("field.tf_of_interest.transforms0.")]
        b = [i for i, c in enumerate(h) if c.startswith("field.tf_of_interest.transforms5.")]
        for r in rows[1::2]:
            for i, j in zip(a, b, strict=True):
                r[i], r[j] = r[j], r[i]
        return rows

    edit_csv(copy, swap)
    swapped = read_demo(copy, frames=["/left_hand_1", "/head_1"])
    for g in ("/left_hand_1", "/head_1"):
        np.testing.assert_allclose(swapped.groups[g], ref.groups[g], equal_nan=True)

    def zero_and_spike(rows):
        h = rows[0]
        p = "field.tf_of_interest.transforms5."
        assert rows[30][h.index(p + "child_frame_id")] == "/left_hand_1"
        for c in (
            "translation.x",
            "translation.y",
            "translation.z",
            "rotation.x",
            "rotation.y",
            "rotation.z",
            "rotation.w",
        ):
            rows[30][h.index(p + "transform." + c)] = "0.0"
        i = h.index(p + "transform.translation.z")
        rows[80][i] = str(float(rows[80][i]) + 1.0)
        return rows

    shutil.copy(path, copy)
    edit_csv(copy, zero_and_spike)
    demo = read_demo(copy, frames=["/left_hand_1"])
    m = demo.missing["/left_hand_1"]
    ref_m = ref.missing.get("/left_hand_1", np.zeros(ref.n_samples, bool))
    assert m.sum() >= ref_m.sum() + 2  # each bad row hides the grid samples next to it
    hand = demo.groups["/left_hand_1"]
    assert np.all(np.isnan(hand[m])) and np.all(np.isfinite(hand[~m]))
    assert np.all(np.linalg.norm(hand[~m], axis=1) > 0.1)  # no all-zero position taken as data
    assert np.nanmax(hand[:, 2]) <= np.nanmax(ref.groups["/left_hand_1"][:, 2]) + 1e-9  # spike removed
    assert m.sum() <= ref.missing.get("/left_hand_1", np.zeros(1, bool)).sum() + 8


def test_flag_jumps_keeps_catch_up_steps():
    t = np.linspace(0, 1, 50)
    pos = np.column_stack([t, 0 * t, 0 * t])
    pos[25:] += 0.35  # a persistent step (tracker catching up): kept
    pos[10] += [0, 0, 0.8]  # an isolated spike: flagged
    pos[40:42] -= [0, 0.6, 0]  # a two-sample spike: flagged
    flags = multimodal.flag_jumps(pos)
    assert set(np.flatnonzero(flags)) == {10, 40, 41}


def test_load_multimodal_task(handover2017_dir):
    ds = load_dataset(handover2017_dir, frames=["/left_hand_1"])
    assert ds.tasks == ["pincer", "screwdriver", "tape"]
    assert [len(ds.demos[t]) for t in ds.tasks] == [31, 30, 29]
    for d in ds.all_demos():
        assert "/left_hand_1" in d.groups and d.extras["hand_position"].shape == (d.n_samples, 3)


# -------------------------------------------------------------------------------- native + loading
@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_native_round_trip(tmp_path, suffix):
    ds = make_synthetic_dataset(n_tasks=2, n_demos=3, seed=3)
    demo = ds.demos["rod"][0]
    m = np.zeros(demo.n_samples, bool)
    m[5:8] = True
    groups = dict(demo.groups)
    groups["/left_hand_1"] = demo.extras["hand_position"].copy()
    groups["/left_hand_1"][m] = np.nan
    from ipromp_pin.data import Demo

    demo = Demo(
        demo.task,
        demo.name,
        demo.source,
        demo.t,
        groups,
        {**demo.channel_names, "/left_hand_1": ("x", "y", "z")},
        missing={"/left_hand_1": m},
        extras=demo.extras,
    )
    path = write_demo(demo, tmp_path / "rod" / f"{demo.name}{suffix}")
    back = read_demo(path)
    assert back.task == "rod" and back.name == demo.name
    assert list(back.groups) == list(demo.groups)
    for g in demo.groups:
        np.testing.assert_allclose(back.groups[g], demo.groups[g], rtol=1e-10, equal_nan=True)
        assert back.channel_names[g] == demo.channel_names[g]
    np.testing.assert_array_equal(back.missing["/left_hand_1"], m)
    np.testing.assert_allclose(back.extras["hand_position"], demo.extras["hand_position"], rtol=1e-10)
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            assert "group0" in z.files
    # A partial demo keeps its full duration in .npz.
    head = demo.head(0.5)
    p2 = write_demo(head, tmp_path / "head.npz")
    assert read_demo(p2).duration_s == pytest.approx(demo.duration_s)


def test_native_bad_files(tmp_path):
    f = tmp_path / "t" / "a.csv"
    f.parent.mkdir()
    f.write_text("t,emg.emg0,emg.emg1\n0.0,1,2\n0.02,nan,2\n0.04,1,2\n")
    with pytest.raises(DataError, match=r"a\.csv: field 'emg/emg0': 1 NaN"):
        read_demo(f)
    f.write_text("t,emg.emg0\n0.0,1\n0.02,1\n0.05,1\n0.06,1\n")
    with pytest.raises(DataError, match="not uniformly spaced"):
        read_demo(f)
    f.write_text("t,emg.emg0\n0.0,1\n0.02,1\n0.04\n")
    with pytest.raises(DataError, match="line 4"):
        read_demo(f)
    f.write_text("t,emg.emg0\n0.0,1\n")
    with pytest.raises(DataError, match="at least 2"):
        read_demo(f)
    f.write_text("time,emg.emg0\n0.0,1\n0.02,1\n")
    with pytest.raises(DataError, match="first column must be 't'"):
        read_demo(f)
    ds = make_synthetic_dataset(n_tasks=1, n_demos=2)
    good = write_demo(ds.demos["rod"][0], tmp_path / "good.npz")
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[:500])
    with pytest.raises(DataError, match=r"cut\.npz: corrupt or truncated"):
        read_demo(cut)


def test_load_dataset_native_and_errors(tmp_path):
    ds = make_synthetic_dataset(n_tasks=2, n_demos=3, seed=5)
    root = tmp_path / "ds"
    write_dataset(ds, root)
    assert detect_format(root / "rod") == "native"
    back = load_dataset(root)
    assert back.tasks == ["rod", "wrench"] and [d.name for d in back.demos["rod"]] == [
        d.name for d in ds.demos["rod"]
    ]
    np.testing.assert_allclose(back.demos["wrench"][2].groups[ROBOT], ds.demos["wrench"][2].groups[ROBOT])

    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="no task sub-folders"):
        load_dataset(empty)
    (empty / "junk").mkdir()
    (empty / "junk" / "notes.txt").write_text("hello")
    with pytest.raises(DataError, match="junk: field 'format': cannot detect"):
        load_dataset(empty)
    for p in list((root / "wrench").iterdir())[1:]:
        p.unlink()
    with pytest.raises(DataError, match="wrench: a task needs at least 2 demos, found 1"):
        load_dataset(root)
    with pytest.raises(DataError, match="unknown format"):
        load_dataset(root, format="hdf5")


def test_native_resampling_and_joint_selection(tmp_path):
    ds = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=2, rate_hz=100.0)
    demo = ds.demos["rod"][0]
    path = write_demo(demo, tmp_path / "rod" / "a.npz")
    kept = read_demo(path, rate_hz=None)
    assert np.allclose(np.diff(kept.t), 0.01)
    at50 = read_demo(path, rate_hz=50.0)
    assert np.allclose(np.diff(at50.t), 0.02) and at50.duration_s == pytest.approx(demo.duration_s)
    np.testing.assert_allclose(at50.groups[ROBOT], demo.groups[ROBOT][::2][: at50.n_samples], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(at50.groups["orientation"], axis=1), 1.0)
    rev = read_demo(path, rate_hz=None, robot_joints=BAXTER_LEFT_JOINTS[::-1])
    np.testing.assert_allclose(rev.groups[ROBOT], demo.groups[ROBOT][:, ::-1])
    with pytest.raises(DataError, match=r"a\.npz: field 'right_s0': unknown joint"):
        read_demo(path, robot_joints=("right_s0",))
    with pytest.raises(DataError, match="/left_hand_1"):
        read_demo(path, frames=["/left_hand_1"])


def test_a_native_dataset_of_another_arm_loads_with_its_own_joints_by_default(tmp_path):
    ds = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=2)
    ur5 = (
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    )
    for i, demo in enumerate(ds.demos["rod"]):
        order = slice(None) if i == 0 else slice(None, None, -1)  # the second file lists them reversed
        names = {**demo.channel_names, ROBOT: ur5[order]}
        q = demo.groups[ROBOT][:, :6][:, order]
        write_demo(
            dataclasses.replace(demo, groups={**demo.groups, ROBOT: q}, channel_names=names),
            tmp_path / "rod" / f"{i}.npz",
        )
    loaded = load_dataset(tmp_path)
    assert [d.channel_names[ROBOT] for d in loaded.demos["rod"]] == [ur5, ur5]
    np.testing.assert_allclose(loaded.demos["rod"][1].groups[ROBOT], ds.demos["rod"][1].groups[ROBOT][:, :6])
    with pytest.raises(DataError, match=r"0\.npz: field 'left_s0': unknown joint name"):
        load_dataset(tmp_path, robot_joints=BAXTER_LEFT_JOINTS)


def test_frames_are_refused_for_chen2017(chen2017_dir):
    with pytest.raises(DataError, match="no tracked frames"):
        read_demo(chen2017_dir / "tape_hold" / "csv" / STAMP, frames=["/left_hand_1"])


def test_multimodal_bad_files(handover2017_dir, tmp_path):
    path = _mm_file(handover2017_dir)
    copy = tmp_path / "pincer" / "csv" / "x" / multimodal.FILE_NAME
    copy.parent.mkdir(parents=True)

    def drop(column):
        def fn(rows):
            i = rows[0].index(column)
            return [r[:i] + r[i + 1 :] for r in rows]

        return fn

    cases = [
        (drop("field.emgStates.ch3"), r"field 'field\.emgStates\.ch3': missing column"),
        (lambda rows: rows[:2], "at least 2 messages"),
        (
            lambda rows: _break(rows, "field.jointStates.position4", lambda r, i: r[7].__setitem__(i, "nan")),
            r"field 'robot/left_s0': 1 NaN",
        ),
    ]
    for edit, pattern in cases:
        shutil.copy(path, copy)
        edit_csv(copy, edit)
        with pytest.raises(DataError, match=pattern) as e:
            read_demo(copy)
        assert "multiModal_states.csv" in str(e.value)


def test_native_csv_columns_in_another_order_read_the_same(tmp_path, tiny):
    ds, _ = tiny
    demo = read_demo(ds / "rod" / "rod_000.npz")
    write_demo(demo, tmp_path / "a.csv")
    lines = (tmp_path / "a.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines]
    order = [0, *range(len(rows[0]) - 1, 0, -1)]  # t first, every other column reversed
    (tmp_path / "b.csv").write_text("\n".join(",".join(r[i] for i in order) for r in rows) + "\n")
    a, b = read_demo(tmp_path / "a.csv"), read_demo(tmp_path / "b.csv", robot_joints=BAXTER_LEFT_JOINTS)
    assert np.array_equal(a.groups["robot"], b.groups["robot"])
    assert a.channel_names["robot"] == b.channel_names["robot"]  # the robot's order, by name
    as_written = read_demo(tmp_path / "b.csv")  # by default, the file's joints in its order
    assert as_written.channel_names["robot"] == BAXTER_LEFT_JOINTS[::-1]
    assert np.array_equal(as_written.groups["robot"], a.groups["robot"][:, ::-1])
    model = IProMP.load(tiny[1])
    pa = model.predict(a.head(0.2, model.observe_))
    pb = model.predict(b.head(0.2, model.observe_))  # emg channels reversed: matched by name
    assert np.array_equal(pa.q_mean, pb.q_mean)


def test_unreadable_or_unknown_task_folder_is_an_error(tmp_path, tiny, monkeypatch):
    ds, _ = tiny
    data = tmp_path / "ds"
    for task in ("rod", "wrench"):
        (data / task).mkdir(parents=True)
        for f in (ds / task).iterdir():
            (data / task / f.name).write_bytes(f.read_bytes())
    real_scandir = os.scandir

    def scandir(path="."):
        if Path(path) == data / "wrench":
            raise PermissionError(13, "Permission denied", str(path))
        return real_scandir(path)

    monkeypatch.setattr(os, "scandir", scandir)  # (as root, chmod 000 does not stop reading)
    with pytest.raises(DataError, match="wrench: cannot read the task folder: Permission denied"):
        load_dataset(data)
    monkeypatch.undo()
    (data / "notes").mkdir()
    (data / "notes" / "todo.txt").write_text("x")
    with pytest.raises(DataError, match="notes: field 'format': cannot detect.*leading '_'"):
        load_dataset(data)
    (data / "notes").rename(data / "_notes")
    assert load_dataset(data).tasks == ["rod", "wrench"]
    (data / "zz").symlink_to(tmp_path / "nowhere")
    with pytest.raises(DataError, match="broken link"):
        load_dataset(data)
