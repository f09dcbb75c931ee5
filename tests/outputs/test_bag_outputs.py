"""The bags as every other trajectory output (issue 24, items 3, 8, 9): marked when written with
--allow-failing-checks, a plainly named ``rosbag.mcap``, and never a user's own file replaced."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import ROBOT_FILE, one_error_line, run_tiny
from rosbags.typesys import Stores, get_typestore

from ipromp_pin.motion.timing import JointLimits, time_path
from ipromp_pin.outputs.rosbag import (
    FAILED_PREFIX,
    TOPIC_CHECKS,
    TOPIC_JOINT_STATES,
    TOPIC_PREFIX,
    BagContent,
    is_our_bag_folder,
    write_ros1_bag,
    write_rosbag2,
)
from ipromp_pin.robot import load_robot

ROS2 = get_typestore(Stores.ROS2_HUMBLE)
ROS1 = get_typestore(Stores.ROS1_NOETIC)


@pytest.fixture(scope="module")
def traj():
    limits = JointLimits.from_robot(load_robot("baxter_left"))
    a = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
    q = a + np.linspace(0, 0.3, 20)[:, None]
    return time_path(q, limits, rate_hz=100.0)[0]


def _read2(folder: Path) -> dict[str, list]:
    from rosbags.rosbag2 import Reader

    out: dict[str, list] = {}
    with Reader(folder) as reader:
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(ROS2.deserialize_cdr(raw, conn.msgtype))
    return out


def _read1(path: Path) -> dict[str, list]:
    from rosbags.rosbag1 import Reader

    out: dict[str, list] = {}
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(ROS1.deserialize_ros1(raw, conn.msgtype))
    return out


@pytest.mark.parametrize("failures", [None, ("workspace",), ("joint_limits", "self_collision", "timing")])
def test_failing_trajectory_is_marked_in_both_bags(traj, tmp_path, failures):
    pose = np.array([0.8, -0.3, 0.2, 0.0, 0.0, 0.0, 1.0])
    content = BagContent(traj, 0.5, pose, failures=failures)
    for msgs in (
        _read2(write_rosbag2(content, tmp_path / "rosbag")),
        _read1(write_ros1_bag(content, tmp_path / "run.bag")),
    ):
        robot_topics = {t for t in msgs if t != TOPIC_CHECKS and not t.startswith(f"{TOPIC_PREFIX}/human")}
        [check] = msgs[TOPIC_CHECKS]
        if failures is None:
            assert check.data == "passed" and TOPIC_JOINT_STATES in robot_topics
            assert not any(t.startswith(FAILED_PREFIX) for t in msgs)
        else:  # nothing on the topics a controller listens on
            assert check.data.startswith(f"checks FAILED ({', '.join(failures)})")
            assert robot_topics and all(t.startswith(FAILED_PREFIX + "/") for t in robot_topics)
            assert len(msgs[FAILED_PREFIX + "/joint_states"]) == traj.n_samples
    meta = (tmp_path / "rosbag" / "metadata.yaml").read_text()
    assert "ipromp_pin.checks" in meta and ('"passed": false' in meta) == (failures is not None)


@pytest.mark.parametrize("name", ["rosbag", ".rosbag.1a2b3c4d.partial", "staged"])
def test_bag_file_is_plainly_named_whatever_the_folder(traj, tmp_path, name):
    folder = write_rosbag2(BagContent(traj, 0.5, np.array([0.8, 0, 0.2, 0, 0, 0, 1.0])), tmp_path / name)
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml", "rosbag.mcap"]
    meta = (folder / "metadata.yaml").read_text()
    assert "- rosbag.mcap" in meta and "partial" not in meta
    assert name == "rosbag" or name not in meta
    assert is_our_bag_folder(folder)


def _far_robot(folder: Path) -> Path:
    text = ROBOT_FILE.read_text()
    text = text.replace("min_m = [0.55, -0.45, -0.08]", "min_m = [5.0, 5.0, 5.0]")
    text = text.replace("max_m = [1.16, 0.45, 0.57]", "max_m = [5.5, 5.5, 5.5]")
    folder.mkdir(exist_ok=True)
    (folder / "far.toml").write_text(text)
    return folder / "far.toml"


def test_run_allowing_failing_checks_marks_the_bags_and_names_the_file(tiny, tmp_path):
    out = tmp_path / "out"
    code = run_tiny(tiny, out, "--robot", str(_far_robot(tmp_path)), "--ros1-bag", "--allow-failing-checks")
    assert code == 3
    assert sorted(os.listdir(out / "rosbag")) == ["metadata.yaml", "rosbag.mcap"]
    for msgs in (_read2(out / "rosbag"), _read1(out / "run.bag")):
        assert msgs[TOPIC_CHECKS][0].data.startswith("checks FAILED (workspace")
        assert TOPIC_JOINT_STATES not in msgs and FAILED_PREFIX + "/joint_states" in msgs
    assert (out / "trajectory.csv").read_text().startswith("# ipromp_pin: checks FAILED (workspace")
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file left


def _user_rosbag_file(out: Path) -> Path:
    (out / "rosbag").write_text("my notes")
    return out / "rosbag"


def _user_file_in_rosbag(out: Path) -> Path:
    (out / "rosbag").mkdir()
    (out / "rosbag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (out / "rosbag" / "mine.txt").write_text("my notes")
    return out / "rosbag" / "mine.txt"


def _unlisted_mcap(out: Path) -> Path:
    (out / "rosbag").mkdir()
    (out / "rosbag" / "metadata.yaml").write_text("relative_file_paths: [other.mcap]\n")
    (out / "rosbag" / "recording.mcap").write_bytes(b"\x89MCAP0\r\n mine")
    return out / "rosbag" / "recording.mcap"


def _symlinked_rosbag(out: Path) -> Path:
    target = out.parent / "elsewhere"
    target.mkdir()
    (target / "keep.txt").write_text("my notes")
    (out / "rosbag").symlink_to(target, target_is_directory=True)
    return target / "keep.txt"


def _user_run_bag(out: Path) -> Path:
    (out / "run.bag").write_text("not a bag")
    return out / "run.bag"


@pytest.mark.parametrize(
    "make", [_user_rosbag_file, _user_file_in_rosbag, _unlisted_mcap, _symlinked_rosbag, _user_run_bag]
)
@pytest.mark.parametrize("extra", [(), ("--no-rosbag",)])
def test_run_never_replaces_a_users_file_named_like_a_bag(tiny, tmp_path, capsys, make, extra):
    out = tmp_path / "out"
    out.mkdir()
    kept = make(out)
    before = kept.read_bytes()
    assert run_tiny(tiny, out, *extra) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "is not a bag written by ipromp_pin" in line and "move it away" in line
    assert kept.read_bytes() == before
    assert not (out / "trajectory.csv").exists() and not (out / "report.json").exists()


def test_run_replaces_its_own_bags_including_the_old_hidden_name(tiny, tmp_path):
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--ros1-bag") == 0
    meta = (out / "rosbag" / "metadata.yaml").read_text()
    old = ".rosbag.0badc0de.partial.mcap"  # as versions before 0.2.1 named it
    (out / "rosbag" / "rosbag.mcap").rename(out / "rosbag" / old)
    (out / "rosbag" / "metadata.yaml").write_text(meta.replace("rosbag.mcap", old))
    assert run_tiny(tiny, out, "--ros1-bag") == 0
    assert sorted(os.listdir(out / "rosbag")) == ["metadata.yaml", "rosbag.mcap"]
    assert json.loads((out / "report.json").read_text())["passed"]
