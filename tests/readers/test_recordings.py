"""Tests of single recordings without a task label: ``read_recording`` in every format,
``expand_recordings`` over files and folders, and bad paths and garbage files refused in one line."""

from __future__ import annotations

import shutil
from pathlib import Path

import helpers_rosbag2 as h
import numpy as np
import pytest

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import (
    UNKNOWN_TASK,
    chen2017,
    expand_recordings,
    read_demo,
    read_recording,
    recording_format,
    write_demo,
)
from ipromp_pin.readers.synthetic import make_synthetic_dataset

CHEN_STAMP = "2017-07-11-15-45-25"


def same_but_task(a: Demo, b: Demo) -> None:
    """``b`` is ``a`` read without its task label."""
    assert b.task == UNKNOWN_TASK and a.task != UNKNOWN_TASK
    assert (b.name, b.n_samples, list(b.groups), b.channel_names) == (
        a.name,
        a.n_samples,
        list(a.groups),
        a.channel_names,
    )
    np.testing.assert_array_equal(b.t, a.t)
    for g in a.groups:
        np.testing.assert_array_equal(b.groups[g], a.groups[g])
    assert sorted(b.extras) == sorted(a.extras) and sorted(b.missing) == sorted(a.missing)


def one_line_error(path: Path, call) -> str:
    """The DataError of ``call()``: one line, naming ``path``."""
    with pytest.raises(DataError) as err:
        call()
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg, msg
    return msg


@pytest.fixture(scope="module")
def synthetic_rosbag2(tmp_path_factory) -> Path:
    """The synthetic recording of helpers_rosbag2 as a rosbag2 folder (MCAP)."""
    return h.write_rosbag2(
        tmp_path_factory.mktemp("rb2") / "2026-12-04-10-00-00", h.Synthetic(seed=2).records()
    )


@pytest.fixture(scope="module")
def native_demo() -> Demo:
    return make_synthetic_dataset(n_tasks=1, n_demos=2, seed=3).demos["rod"][0]


# ----------------------------------------------------------------------------------- read_recording
def test_read_recording_native_and_rosbag2(tmp_path, synthetic_rosbag2, native_demo):
    """Native .npz / .csv files and a rosbag2 folder or its bare .mcap read as read_demo reads them,
    without the task: the folder's name and a task stored in the file are not labels."""
    for suffix in (".npz", ".csv"):
        path = write_demo(native_demo, tmp_path / "rod" / f"demo_1{suffix}")
        assert recording_format(path) == "native"
        same_but_task(read_demo(path), read_recording(path))
    assert recording_format(synthetic_rosbag2) == "rosbag2"
    same_but_task(read_demo(synthetic_rosbag2, "t"), read_recording(synthetic_rosbag2))
    bare = tmp_path / "bare" / "2026-12-04-10-00-00.mcap"
    bare.parent.mkdir()
    shutil.copy(next(synthetic_rosbag2.glob("*.mcap")), bare)
    same_but_task(read_demo(synthetic_rosbag2, "t"), read_recording(bare))
    # the storage file inside its folder names the folder's recording
    assert expand_recordings([next(synthetic_rosbag2.glob("*.mcap"))]) == [synthetic_rosbag2]
    demo = read_recording(synthetic_rosbag2, frames=["/left_hand_1"])
    assert "/left_hand_1" in demo.groups and demo.task == ""


@pytest.mark.realdata
def test_read_recording_of_the_recorded_formats(chen2017_dir, handover2017_dir, tmp_path):
    """A ROS 1 bag, one chen2017 stamp (any of its CSV files, their prefix, or a folder holding only
    them, anywhere), a multimodal CSV or its folder: the demo of read_demo, task unknown."""
    task = chen2017_dir / "tape_hold"
    bag = task / f"{CHEN_STAMP}.bag"
    same_but_task(read_demo(bag), read_recording(bag))
    reference = read_demo(task / "csv" / CHEN_STAMP)
    loose = tmp_path / "my recording"
    loose.mkdir()
    for suffix in chen2017.TOPIC_SUFFIXES.values():
        shutil.copy(task / "csv" / f"{CHEN_STAMP}-{suffix}.csv", loose)
    for path in (
        task / "csv" / CHEN_STAMP,
        loose / f"{CHEN_STAMP}-robot-joint_states.csv",
        loose / CHEN_STAMP,
        loose,
    ):
        assert recording_format(path if path != loose else loose / CHEN_STAMP) == "chen2017"
        same_but_task(reference, read_recording(path))
    mm = sorted((handover2017_dir / "tape" / "csv").glob("*/multiModal_states.csv"))[0]
    reference = read_demo(mm, frames=["/left_hand_1"])
    for path in (mm, mm.parent):
        same_but_task(reference, read_recording(path, frames=["/left_hand_1"]))


def test_read_recording_with_other_topic_names(tmp_path, native_demo):
    """A recording on other topics than the defaults reads with ``topics=``; without it the missing
    topic is named; a format without topics refuses them."""
    renamed = {"/myo_raw_emg_pub": "/myo/emg", "/myo_raw_imu_pub": "/myo/imu", "/tf": "/tracker/tf"}
    records = [(renamed.get(t, t), m, ns, msg) for t, m, ns, msg in h.Synthetic(seed=2).records()]
    folder = h.write_rosbag2(tmp_path / "renamed", records)
    msg = one_line_error(folder, lambda: read_recording(folder))
    assert "field '/myo_raw_emg_pub': topic missing" in msg and "/myo/emg" in msg
    demo = read_recording(folder, topics={"emg": "/myo/emg", "imu": "/myo/imu"})
    assert demo.task == UNKNOWN_TASK and "acc" in demo.groups
    assert not any(k.startswith("skeleton:") for k in demo.extras)  # /tracker/tf is not a default TF topic
    demo = read_recording(folder, topics={"emg": "/myo/emg", "imu": "/myo/imu", "tf": "/tracker/tf"})
    assert "skeleton:/head_1" in demo.extras
    path = write_demo(native_demo, tmp_path / "d.npz")
    assert "no topics to choose" in one_line_error(path, lambda: read_recording(path, topics={"emg": "/e"}))


# -------------------------------------------------------------------------------- expand_recordings
def test_expand_recordings_files_folders_and_nesting(tmp_path, synthetic_rosbag2, native_demo):
    """One recording per file or recording folder; a folder of recordings expands to each, by name;
    sub-folders (a dataset) in turn, ``_`` and hidden ones left out; each recording once."""
    many = tmp_path / "many"
    shutil.copytree(synthetic_rosbag2, many / "r1")
    shutil.copy(next(synthetic_rosbag2.glob("*.mcap")), many / "r2.mcap")
    native = tmp_path / "native"
    for name in ("b", "a"):
        write_demo(native_demo, native / f"{name}.npz")
    (native / "notes.txt").write_text("not a recording, ignored in a folder")
    nested = tmp_path / "dataset"
    for task in ("give", "take"):
        write_demo(native_demo, nested / task / "d0.csv")
        write_demo(native_demo, nested / task / "d1.csv")
    (nested / "_scratch").mkdir()
    (nested / "_scratch" / "junk.bin").write_bytes(b"\0")
    (nested / ".hidden").mkdir()
    found = expand_recordings([many, native / "b.npz", native, nested, many / "r1"])
    assert found == [
        many / "r1",
        many / "r2.mcap",
        native / "b.npz",
        native / "a.npz",
        nested / "give" / "d0.csv",
        nested / "give" / "d1.csv",
        nested / "take" / "d0.csv",
        nested / "take" / "d1.csv",
    ]
    assert [recording_format(p) for p in found[:3]] == ["rosbag2", "rosbag2", "native"]
    msg = one_line_error(native, lambda: read_recording(native))
    assert "holds 2 recordings, not one" in msg


@pytest.mark.realdata
def test_expand_a_chen2017_task_folder_reads_its_csv_export_once(chen2017_dir, handover2017_dir):
    """The task folder holds the CSV export and the original bags of the same 30 demos: each once,
    as the CSV stamps (what load_dataset reads); a dataset folder expands to every task's demos."""
    found = expand_recordings([chen2017_dir / "tape_hold"])
    assert found == chen2017.list_demos(chen2017_dir / "tape_hold", "recorded")
    assert len(expand_recordings([chen2017_dir])) == 99
    assert len(expand_recordings([handover2017_dir])) == 90


def test_bad_paths_and_folders(tmp_path, synthetic_rosbag2, native_demo):
    """Nothing there, no path, an empty folder, a sub-folder without recordings, a folder mixing
    formats, a file of no recording format: one-line errors naming the path."""
    one_line_error(tmp_path / "nope", lambda: expand_recordings([tmp_path / "nope"]))
    with pytest.raises(DataError, match="no recording given"):
        expand_recordings([])
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "no recording found" in one_line_error(empty, lambda: read_recording(empty))
    dataset = tmp_path / "dataset"
    write_demo(native_demo, dataset / "give" / "d0.npz")
    (dataset / "take").mkdir()
    msg = one_line_error(dataset / "take", lambda: expand_recordings([dataset]))
    assert "leading '_'" in msg
    mixed = tmp_path / "mixed"
    write_demo(native_demo, mixed / "d0.npz")
    shutil.copytree(synthetic_rosbag2, mixed / "r1")
    (mixed / "old.bag").write_bytes(b"#ROSBAG V2.0\n")
    msg = one_line_error(mixed, lambda: expand_recordings([mixed]))
    assert "several formats (1 native, 1 bag, 1 rosbag2)" in msg
    notes = tmp_path / "notes.txt"
    notes.write_text("hello")
    assert "not a recording" in one_line_error(notes, lambda: read_recording(notes))


def test_garbage_files_give_one_line_errors(tmp_path, synthetic_rosbag2):
    """A truncated MCAP, a .db3 that is no SQLite database, text in a .bag, an .npz or a
    multiModal_states.csv, binary bytes in a native .csv, a rosbag2 folder without storage."""
    mcap = next(synthetic_rosbag2.glob("*.mcap")).read_bytes()
    garbage = {
        "cut.mcap": mcap[: len(mcap) // 3],
        "head.mcap": mcap[:8],
        "text.db3": b"SELECT nothing;\n",
        "text.bag": b"hello\n",
        "text.npz": b"hello\n",
        "bytes.csv": bytes(range(256)),
        "multiModal_states.csv": b"",
    }
    for name, data in garbage.items():
        folder = tmp_path / name.replace(".", "_")
        folder.mkdir()
        path = folder / name
        path.write_bytes(data)
        one_line_error(path, lambda path=path: read_recording(path))
    no_storage = tmp_path / "no_storage"
    shutil.copytree(synthetic_rosbag2, no_storage)
    for p in no_storage.glob("*.mcap"):
        p.unlink()
    assert "without .mcap or .db3" in one_line_error(no_storage, lambda: read_recording(no_storage))
