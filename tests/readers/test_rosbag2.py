"""Tests of the rosbag2 reader: recordings written to rosbag2 (MCAP and SQLite) with their original
header stamps and receive times read back to the demo their original format gives; a synthetic
recording in standard ROS 2 types against its known motion; the message types the project's own
bag writer uses for the human channels read back; bad recordings refused in one line."""

from __future__ import annotations

import csv
import re
import shutil
from pathlib import Path

import helpers_rosbag2 as h
import numpy as np
import pytest

from ipromp_pin.data import ROBOT, Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import count_demos, detect_format, load_dataset, read_demo, rosbag2
from ipromp_pin.readers.streams import RawRecording, RawStream, assemble_recording
from ipromp_pin.readers.tracked import TrackedTopic

STORAGES = ("mcap", "sqlite3")
CHEN_STAMP = "2017-07-11-15-45-25"  # a tape_hold demo
FRAMES = ["/left_hand_1"]


def assert_same_demo(a: Demo, b: Demo, atol: float = 0.0, emg_atol: float = 0.0) -> None:
    """Same groups, channel names, times, missing samples and extras; values within ``atol`` (units
    of the group: rad, m, g, unit quaternion), the EMG envelope within ``emg_atol``."""
    assert (b.task, b.name, b.n_samples) == (a.task, a.name, a.n_samples)
    np.testing.assert_array_equal(b.t, a.t)
    assert list(b.groups) == list(a.groups) and b.channel_names == a.channel_names
    for g in a.groups:
        tol = emg_atol if g == "emg" else atol
        np.testing.assert_allclose(b.groups[g], a.groups[g], rtol=0, atol=tol, err_msg=g)
    assert sorted(b.missing) == sorted(a.missing)
    for g in a.missing:
        np.testing.assert_array_equal(b.missing[g], a.missing[g])
    assert sorted(b.extras) == sorted(a.extras)
    for k in a.extras:
        np.testing.assert_allclose(b.extras[k], a.extras[k], rtol=0, atol=atol, err_msg=k)


# ------------------------------------------------------------------------- chen2017: ROS 1 bag
@pytest.mark.realdata
@pytest.mark.parametrize("storage", STORAGES)
def test_chen2017_demo_written_to_rosbag2_reads_as_its_ros1_bag(chen2017_dir, tmp_path, storage):
    """Every message of the four topics with its header stamp and record time, the Myo's and
    Baxter's own types with the definitions the writer stores: the same demo as the ROS 1 bag, to
    the last bit (both readers turn the same integer stamps into seconds)."""
    bag = chen2017_dir / "tape_hold" / f"{CHEN_STAMP}.bag"
    folder = h.write_rosbag2(tmp_path / "tape_hold" / CHEN_STAMP, h.chen2017_records(bag), storage)
    assert {p.suffix for p in folder.iterdir()} == {".yaml", ".mcap" if storage == "mcap" else ".db3"}
    assert_same_demo(read_demo(bag), read_demo(folder))
    # the storage file alone (no metadata.yaml beside it) reads the same
    alone = tmp_path / f"{CHEN_STAMP}{'.mcap' if storage == 'mcap' else '.db3'}"
    shutil.copy(next(p for p in folder.iterdir() if p.suffix != ".yaml"), alone)
    assert_same_demo(read_demo(bag, "x"), read_demo(alone, "x"))


@pytest.mark.realdata
def test_ros1_bag_converted_by_rosbags_reads_the_same(chen2017_dir, tmp_path):
    """``rosbags-convert`` (how a ROS 1 bag becomes a rosbag2: docs/your_data.md) keeps stamps,
    record times and the bag's own definitions: the same demo, also compressed (zstd, per file or
    per message)."""
    from rosbags.convert.converter import convert

    bag = chen2017_dir / "tape_hold" / f"{CHEN_STAMP}.bag"
    for storage, compress, mode in (
        ("mcap", None, "file"),
        ("mcap", "zstd", "file"),
        ("sqlite3", "zstd", "message"),
    ):
        dst = tmp_path / f"{storage}_{compress}_{mode}" / CHEN_STAMP
        convert([bag], dst, storage, 8, compress, mode, None, None, [], [], [], [])
        assert_same_demo(read_demo(bag), read_demo(dst, "tape_hold"))


@pytest.mark.realdata
def test_dataset_of_rosbag2_task_folders(chen2017_dir, tmp_path):
    """Task folders of rosbag2 recordings are detected (one folder per demo, or bare files) and load as
    the ROS 1 bags do, in the same order."""
    root = tmp_path / "ds"
    expected = {}
    for task in ("aluminum_hold", "tape_hold"):
        bags = sorted((chen2017_dir / task).glob("*.bag"))[:2]
        expected[task] = [read_demo(b) for b in bags]
        h.write_rosbag2(root / task / bags[0].stem, h.chen2017_records(bags[0]), "mcap")
        folder = h.write_rosbag2(tmp_path / "one", h.chen2017_records(bags[1]), "sqlite3")
        shutil.copy(folder / "one.db3", root / task / f"{bags[1].stem}.db3")
        shutil.rmtree(folder)
        assert detect_format(root / task) == "rosbag2"
    assert count_demos(root) == {"aluminum_hold": 2, "tape_hold": 2}
    ds = load_dataset(root)
    for task, demos in expected.items():
        for a, b in zip(demos, ds.demos[task], strict=True):
            assert_same_demo(a, b)


@pytest.mark.realdata
def test_sqlite_without_definitions_refuses_the_custom_types(chen2017_dir, tmp_path):
    """ROS 2 Humble's SQLite bags carry no definitions: the Myo's custom type is unknown, named."""
    bag = chen2017_dir / "tape_hold" / f"{CHEN_STAMP}.bag"
    folder = h.write_rosbag2(tmp_path / "b", h.chen2017_records(bag), "sqlite3")
    h.drop_definitions(folder / "b.db3")
    with pytest.raises(DataError) as err:
        read_demo(folder)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(folder))
    assert re.search(
        r"field '/myo_raw_(emg|imu)_pub': message type myo_driver/msg/(emg|imu)State is not a standard", msg
    )


# --------------------------------------------------------------- handover_20171128: multimodal
def _deduplicated_csv(src: Path, dst: Path) -> Path:
    """A copy of a ``multiModal_states.csv`` where a bundled message repeated in later rows (a stale
    message, same header stamp) counts once: its repeats' stamps are 0, the CSV's placeholder for
    "not received", which the reader skips."""
    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    for prefix in ("emgStates", "imuStates", "jointStates", "endpointStates"):
        j = rows[0].index(f"field.{prefix}.header.stamp")
        seen: set[str] = set()
        for r in rows[1:]:
            if r[j] in seen:
                r[j] = "0"
            seen.add(r[j])
    dst.parent.mkdir(parents=True, exist_ok=True)
    with open(dst, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return dst


@pytest.mark.realdata
@pytest.mark.parametrize("storage", STORAGES)
def test_multimodal_demo_written_to_rosbag2_reads_as_its_csv(handover2017_dir, tmp_path, storage):
    """The bundled messages as separate topics (each once, with its header stamp and receive time;
    the Myo IMU as ``sensor_msgs/Imu`` with raw integers as recorded; the tracked frames as
    ``tf2_msgs/TFMessage``): the same demo as the CSV, skeleton, hand and missing samples included.

    Compared with the CSV read with each message counted once: the CSV repeats a stale message in
    later rows with later receive times, which the CSV reader's clock-offset estimate counts (it
    shifts its streams by milliseconds against the rosbag2's). Tolerance 1e-4 (rad, m, g, unit
    quaternion; 1e-3 on the EMG envelope): the CSV's stamps are nanosecond integers read as floats
    (0.25 us steps at 1.5e9 s), the rosbag2's exact.
    """
    src = sorted((handover2017_dir / "tape" / "csv").glob("*/multiModal_states.csv"))[0]
    stamp = src.parent.name
    folder = h.write_rosbag2(tmp_path / "tape" / stamp, h.multimodal_records(src), storage)
    csv_once = _deduplicated_csv(src, tmp_path / "csv" / "tape" / "csv" / stamp / "multiModal_states.csv")
    a = read_demo(csv_once, "tape", frames=FRAMES)
    b = read_demo(folder, frames=FRAMES)
    assert "skeleton:/head_1" in b.extras and "hand_position" in b.extras and "endpoint_pose" in b.extras
    assert b.missing["/left_hand_1"].any()  # the recording's occlusions survive the round trip
    assert_same_demo(a, b, atol=1e-4, emg_atol=1e-3)


# ------------------------------------------------------------------ synthetic, standard ROS 2 types
@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """The synthetic recording (helpers_rosbag2.Synthetic) written in both storages."""
    rec = h.Synthetic(seed=4)
    records = rec.records()
    root = tmp_path_factory.mktemp("synthetic")
    return rec, {s: h.write_rosbag2(root / s, records, s) for s in STORAGES}


def _expected(rec: h.Synthetic) -> Demo:
    """The demo of the synthetic streams built from their arrays directly (not through a bag)."""
    hs, rs, tf_h = rec.emg, rec.imu, rec.tf
    tracked = TrackedTopic(tf_h[0], tf_h[1], rec.tf_positions, "tf")
    raw = RawRecording(
        emg=RawStream(hs[0], hs[1], hs[2], "emg"),
        imu=RawStream(rs[0], rs[1], rs[2], "imu"),
        joints=RawStream(*rec.joints, "joints"),
        endpoint=RawStream(*rec.endpoint, "endpoint"),
        imu_scales=(1.0, h.STANDARD_GRAVITY_MS2),
        tracked=[tracked],
    )
    return assemble_recording(
        raw, task="syn", name="mcap", source="x", rate_hz=50.0, robot_joints=h.ARM, frames=FRAMES
    )


@pytest.mark.parametrize("storage", STORAGES)
def test_synthetic_recording_in_standard_types(synthetic, storage):
    """EMG as ``Float32MultiArray`` (no header: its record times), an SI ``sensor_msgs/Imu``, joint
    states and a ``PoseStamped`` end-point on a robot clock 4 s ahead, TF frames in the base frame
    (and one in another parent, not read): the demo of the same streams built directly, and the
    motion the streams were made from."""
    rec, folders = synthetic
    demo = read_demo(folders[storage], "syn", frames=FRAMES)
    expected = _expected(rec)
    assert_same_demo(
        Demo(
            "syn",
            "mcap",
            "x",
            expected.t,
            expected.groups,
            expected.channel_names,
            expected.missing,
            expected.extras,
        ),
        Demo("syn", "mcap", "x", demo.t, demo.groups, demo.channel_names, demo.missing, demo.extras),
        atol=1e-6,
        emg_atol=1e-6,
    )
    # Against the motion: the true time each stream's sample says, on one clock (the robot's 4 s
    # removed; within the streams' 1-4 ms latencies and the 20 ms grid's interpolation).
    tau_robot = (demo.groups[ROBOT][:, 0] - h.Q_START[0]) / (h.Q_END[0] - h.Q_START[0]) * rec.duration_s
    w, x = demo.groups["orientation"][:, 0], demo.groups["orientation"][:, 1]
    tau_imu = 2.0 * 2.0 * np.arctan2(x, w)  # angle = 0.5 tau, q = (cos(angle/2), sin(angle/2), 0, 0)
    ok = ~demo.missing["/left_hand_1"]
    tau_hand = (demo.groups["/left_hand_1"][ok, 0] - 0.3) / 0.2
    assert np.max(np.abs(tau_imu - tau_robot)) < 0.01
    assert np.max(np.abs(tau_hand - tau_robot[ok])) < 0.01
    np.testing.assert_allclose(np.linalg.norm(demo.groups["acc"], axis=1), 1.0, atol=1e-3)  # [g]
    # the gaps: every 7th TF message lacks the hand, message 40 lists it as zeros
    assert 0.15 < demo.missing["/left_hand_1"].mean() < 0.5
    assert "skeleton:/head_1" in demo.extras and "skeleton:camera" not in demo.extras


def test_quaternion_stamped_orientation_gives_no_acceleration(tmp_path):
    """An orientation-only IMU topic (``geometry_msgs/QuaternionStamped``, as the project's bags carry
    the forearm): the demo has orientation and no ``acc``; a norm that is neither 1 nor the Myo's
    16384 is refused, naming the field."""
    rec = h.Synthetic(seed=5)
    records = []
    for topic, msgtype, ns, msg in rec.records():
        if topic == "/myo_raw_imu_pub":
            msgtype = h.QUATERNION_STAMPED
            msg = h.T(msgtype)(header=msg.header, quaternion=msg.orientation)
        records.append((topic, msgtype, ns, msg))
    demo = read_demo(h.write_rosbag2(tmp_path / "q", records), "q")
    assert "acc" not in demo.groups and "orientation" in demo.groups
    np.testing.assert_allclose(np.linalg.norm(demo.groups["orientation"], axis=1), 1.0, atol=1e-9)
    scaled = []
    for topic, msgtype, ns, msg in records:
        if topic == "/myo_raw_imu_pub":
            q = msg.quaternion
            msg = h.T(msgtype)(
                header=msg.header, quaternion=h.quaternion([3 * q.x, 3 * q.y, 3 * q.z, 3 * q.w])
            )
        scaled.append((topic, msgtype, ns, msg))
    with pytest.raises(DataError, match=r"/myo_raw_imu_pub: field '\.quaternion': median quaternion norm 3:"):
        read_demo(h.write_rosbag2(tmp_path / "q3", scaled), "q")


def test_project_bag_writer_human_types_read_back(tmp_path):
    """The message types the project writes for the human channels (``outputs.rosbag``:
    ``QuaternionStamped``, ``PointStamped`` in the base frame, ``Float64MultiArray``) read back to
    the observed values at their stamps, with the topics mapped by ``topics=``."""
    from ipromp_pin.motion.trajectory import Trajectory
    from ipromp_pin.outputs.rosbag import BagContent, write_rosbag2

    n = 30
    t = np.arange(n) * 0.02
    a = 0.3 * t
    groups = {
        "orientation": np.column_stack([np.cos(a), np.sin(a), 0 * a, 0 * a]),
        "emg": 20.0 + np.arange(8) + t[:, None],
        "/left_hand_1": np.column_stack([0.4 + t, 0.1 + 0 * t, 0.3 + 0 * t]),
    }
    missing = {"/left_hand_1": np.arange(n) % 5 == 2}
    groups["/left_hand_1"][missing["/left_hand_1"]] = np.nan
    names = {"orientation": ("qw", "qx", "qy", "qz"), "emg": tuple(f"emg{i}" for i in range(8))}
    names["/left_hand_1"] = ("x", "y", "z")
    obs = Demo("t", "d", "s", t, groups, names, missing)
    ts = np.linspace(0, 1, 11)
    q = np.tile(h.Q_START, (11, 1))
    traj = Trajectory(ts, q, 0 * q, 0 * q, h.ARM)
    start_ns = 1_700_000_000 * 10**9
    folder = write_rosbag2(
        BagContent(traj, 0.6, np.array([0.8, 0, 0.2, 0, 0, 0, 1.0]), "base", obs, start_ns), tmp_path / "b"
    )
    topics = {
        "emg": "/ipromp_pin/human/emg",
        "imu": "/ipromp_pin/human/orientation",
        "joints": "/ipromp_pin/joint_states",
        "frame:/left_hand_1": "/ipromp_pin/human/left_hand_1",
    }
    raw = rosbag2.read_raw(folder, topics=topics)
    stamps = start_ns * 1e-9 + t
    np.testing.assert_allclose(raw.emg.receive_s, stamps, atol=1e-6)
    np.testing.assert_allclose(raw.emg.values, groups["emg"], atol=1e-12)
    np.testing.assert_allclose(raw.imu.header_s, stamps, atol=1e-6)
    np.testing.assert_allclose(raw.imu.values, groups["orientation"], atol=1e-12)
    assert raw.imu_scales == (1.0, rosbag2.STANDARD_GRAVITY)
    np.testing.assert_allclose(raw.joints.values, q, atol=1e-12)
    [hand] = raw.tracked
    ok = ~missing["/left_hand_1"]  # missing samples are not written
    np.testing.assert_allclose(hand.header_s, stamps[ok], atol=1e-6)
    np.testing.assert_allclose(hand.positions["/left_hand_1"], groups["/left_hand_1"][ok], atol=1e-12)


# ------------------------------------------------------------------------------------ bad input
def _one_line(err: pytest.ExceptionInfo, path: Path) -> str:
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_bad_rosbag2_recordings(synthetic, tmp_path):
    """Truncated, empty, foreign or malformed storage and metadata, a missing topic, a wrong type on a
    topic, mixed stamps: one-line errors naming the file (and field)."""
    _, folders = synthetic
    mcap = folders["mcap"] / "mcap.mcap"
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    with pytest.raises(DataError, match=r"corrupt or unreadable rosbag2") as err:
        read_demo(cut, "x")
    _one_line(err, cut)
    fake = tmp_path / "fake.db3"
    fake.write_text("not a database\n")
    with pytest.raises(DataError, match=r"not an SQLite database") as err:
        read_demo(fake, "x")
    _one_line(err, fake)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(DataError, match=r"empty\.mcap: empty file"):
        read_demo(empty, "x")
    broken = tmp_path / "broken"
    shutil.copytree(folders["mcap"], broken)
    (broken / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    with pytest.raises(DataError, match="corrupt or unreadable rosbag2") as err:
        read_demo(broken, "x")
    _one_line(err, broken)
    (broken / "mcap.mcap").unlink()
    with pytest.raises(DataError, match="without .mcap or .db3 storage files"):
        read_demo(broken, "x")
    with pytest.raises(
        DataError, match=r"field '/no/emg': topic missing or without messages \(the bag's topics: "
    ):
        rosbag2.read_demo(folders["mcap"], "x", topics={"emg": "/no/emg"})
    with pytest.raises(
        DataError, match=r"mcap:/tf: message type tf2_msgs/msg/TFMessage cannot be read as EMG"
    ):
        rosbag2.read_demo(folders["mcap"], "x", topics={"emg": "/tf"})
    with pytest.raises(DataError, match=r"unknown stream 'gaze'"):
        rosbag2.read_demo(folders["mcap"], "x", topics={"gaze": "/gaze"})
    with pytest.raises(
        DataError, match=r"field '/left_foot_1': frame never tracked in the base frame .*world->camera"
    ):
        read_demo(folders["mcap"], "x", frames=["/left_foot_1"])
    with pytest.raises(
        DataError, match=r"field 'camera': frame never tracked in the base frame .*transforms are not"
    ):
        read_demo(folders["mcap"], "x", frames=["camera"])


def test_mixed_stamps_and_frames_outside_the_base_frame_are_refused(tmp_path):
    rec = h.Synthetic(seed=6)
    records = rec.records()
    mixed = []
    for k, (topic, msgtype, ns, msg) in enumerate(records):
        if topic == "/myo_raw_imu_pub" and k % 3 == 0:
            msg = h.imu(
                0, [msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z], [0, 0, 9.8]
            )
        mixed.append((topic, msgtype, ns, msg))
    with pytest.raises(
        DataError, match=r"/myo_raw_imu_pub: field 'header.stamp': \d+ of \d+ messages are stamped 0"
    ):
        read_demo(h.write_rosbag2(tmp_path / "mixed", mixed), "x")
    points = records + [
        (
            "/hand",
            h.POINT_STAMPED,
            h.START_NS + k * 10**7,
            h.T(h.POINT_STAMPED)(
                header=h.header(h.START_NS + k * 10**7, "camera"),
                point=h.T("geometry_msgs/msg/Point")(x=0.1, y=0.0, z=0.0),
            ),
        )
        for k in range(10)
    ]
    with pytest.raises(
        DataError, match=r"/hand: field 'header.frame_id': message 0: 'camera' is not the robot's base frame"
    ):
        rosbag2.read_demo(h.write_rosbag2(tmp_path / "points", points), "x", topics={"frame:/hand": "/hand"})
