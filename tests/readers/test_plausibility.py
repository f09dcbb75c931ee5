"""Finite but absurd values are refused by the readers, naming file, field and value (issue class 1);
recordings without their optional end-point stream still load."""

from __future__ import annotations

import csv
import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.app.calibrate import run_calibration
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import load_dataset, plausibility, read_demo, write_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot

DEMO = Path("rod") / "rod_001.npz"


@pytest.fixture(scope="module")
def native_ds(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("native")
    write_dataset(make_synthetic_dataset(n_tasks=2, n_demos=4, seed=3), root)
    return root


@pytest.fixture(scope="module")
def limits() -> dict:
    return load_robot("baxter_left").recorded_joint_limits()


def _edit(src: Path, dst: Path, change) -> Path:
    shutil.copytree(src, dst)
    path = dst / DEMO
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez_compressed(path, **arrays)
    return dst


def _group(arrays: dict, name: str) -> str:
    return f"group{arrays['groups'].tolist().index(name)}"


def _set(group: str, fn):
    def change(a):
        key = _group(a, group)
        v = a[key].astype(float)
        fn(v)
        a[key] = v

    return change


def _extra(name: str, fn):
    def change(a):
        key = f"extra{a['extras'].tolist().index(name)}"
        v = a[key].astype(float)
        fn(v)
        a[key] = v

    return change


def _cut(fraction: float):
    def change(a):
        n = int(a["t"].size * fraction)
        a["t"] = a["t"][:n]
        for i in range(len(a["groups"])):
            a[f"group{i}"] = a[f"group{i}"][:n]
        for j in range(len(a["extras"])):
            a[f"extra{j}"] = a[f"extra{j}"][:n]
        a["duration_s"] = np.array(float(a["t"][-1]))

    return change


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        (_set("robot", lambda v: v.__setitem__((5, 0), 100.0)), "robot/left_s0", "joint angle 100 rad"),
        (_set("robot", lambda v: v.__setitem__((5, 3), 1e300)), "robot/left_e1", "joint angle 1e.300"),
        (_set("robot", lambda v: v.__imul__(180 / np.pi)), "robot/", "degrees"),
        (_set("robot", lambda v: v.__setitem__((slice(20, None), 2), 3.3)), "robot/left_e0", "3.3 rad"),
        (_set("orientation", lambda v: v.__imul__(3.0)), "orientation", "implausible component"),
        (_set("orientation", lambda v: v.__imul__(0.5)), "orientation", r"norm 0.5 .*\[0.9, 1.1\]"),
        (_set("orientation", lambda v: v.__setitem__((4, 1), 1e200)), "orientation", "component 1e.200"),
        (_set("emg", lambda v: v.__setitem__((9, 2), 1e300)), "emg/emg2", "1e.300"),
        (_set("emg", lambda v: v.__setitem__((9, 2), -5e7)), "emg/emg2", "-5e.07"),
        (_set("emg", lambda v: v.__imul__(0.0)), "emg", "constant"),
        (_set("acc", lambda v: v.__setitem__((3, 0), 1e300)), "acc", "component 1e.300 g"),
        (_set("acc", lambda v: v.__setitem__((3, 0), 40.0)), "acc", r"component 40 g .*\[0, 16\] g"),
        (_set("acc", lambda v: v.__setitem__((3, slice(None)), 10.0)), "acc", r"norm 17.3\d* g"),
        (_extra("hand_position", lambda v: v.__setitem__(slice(40, None), 1e300)), "hand_position", "m"),
        (_cut(0.12), "duration", "of its task"),
        (_cut(0.3), "duration", "of its task"),
    ],
)
def test_implausible_native_values_are_refused(tmp_path, native_ds, limits, change, field, message):
    data = _edit(native_ds, tmp_path / "ds", change)
    with pytest.raises(DataError, match=message) as info:
        load_dataset(data, joint_limits=limits)
    err = info.value
    assert str(DEMO) in str(err.source) and field in (err.field or ""), str(err)
    assert "\n" not in str(err)


def test_plausible_variations_still_load(tmp_path, native_ds, limits):
    # stronger muscle activity and a faster demo are plausible; so is a recording with no extras
    data = _edit(native_ds, tmp_path / "ds", _set("emg", lambda v: v.__imul__(3.0)))
    ds = load_dataset(data, joint_limits=limits)
    assert len(ds.all_demos()) == 8


def test_generic_joint_bound_without_robot_limits(tmp_path, native_ds):
    # no robot given: one turn plus the margin; 100 rad is refused, 3.2 rad (beyond Baxter's s0) is not
    data = _edit(native_ds, tmp_path / "a", _set("robot", lambda v: v.__setitem__((5, 0), 100.0)))
    with pytest.raises(DataError, match="joint angle 100"):
        read_demo(data / DEMO)
    data = _edit(native_ds, tmp_path / "b", _set("robot", lambda v: v.__setitem__((5, 0), 3.2)))
    assert read_demo(data / DEMO).groups["robot"][5, 0] == 3.2
    with pytest.raises(DataError, match="left_s0"):
        read_demo(data / DEMO, joint_limits=load_robot("baxter_left").recorded_joint_limits())


def test_duration_check_needs_three_demos_per_task():
    demos = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=0).demos
    short = dataclasses.replace(demos["rod"][0].slice(10), duration_s=None)  # a recording cut short
    plausibility.check_durations({"rod": [short, demos["rod"][1]]})  # two demos: no median to judge
    with pytest.raises(DataError, match="duration"):
        plausibility.check_durations({"rod": [short, *demos["rod"], demos["rod"][1]]})


# ------------------------------------------------------------------------------- real recordings
def _copy_multimodal(src: Path, dst: Path, per_task: int = 2) -> Path:
    for task in ("pincer", "tape"):
        for stamp in sorted((src / task / "csv").iterdir())[:per_task]:
            out = dst / task / "csv" / stamp.name
            out.mkdir(parents=True)
            shutil.copy(stamp / "multiModal_states.csv", out / "multiModal_states.csv")
    return dst


def _edit_csv(path: Path, change) -> None:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    change(rows)
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def _set_columns(prefix: str, value: str, rows_sel=slice(1, None)):
    def change(rows):
        idx = [i for i, h in enumerate(rows[0]) if h.startswith(prefix)]
        for r in rows[rows_sel]:
            for i in idx:
                r[i] = value

    return change


@pytest.mark.realdata
def test_multimodal_session_without_end_point_loads(tmp_path, handover2017_dir):
    data = _copy_multimodal(handover2017_dir, tmp_path / "mm")
    first = sorted(data.glob("*/csv/*/multiModal_states.csv"))[0]
    reference = read_demo(first, frames=["/left_hand_1"])
    _edit_csv(first, _set_columns("field.endpointStates.header.stamp", "0"))
    demo = read_demo(first, frames=["/left_hand_1"])
    assert "endpoint_pose" not in demo.extras
    # the handing hand is found against the tracked gripper frame instead: the same hand
    np.testing.assert_array_equal(demo.extras["hand_position"], reference.extras["hand_position"])
    np.testing.assert_array_equal(demo.groups["robot"], reference.groups["robot"])
    # and, without the gripper frame either, against the forward kinematics of the recorded joints
    _edit_csv(first, lambda rows: [r.__setitem__(i, "") for r in rows[1:] for i, h in enumerate(rows[0])
                                   if h.endswith("child_frame_id") and r[i] == "left_gripper"])  # fmt: skip
    robot = load_robot("baxter_left")
    assert "hand_position" not in read_demo(first).extras  # nothing to compare the hands with
    demo = read_demo(first, end_effector=lambda q: robot_ee(robot, q))
    np.testing.assert_array_equal(demo.extras["hand_position"], reference.extras["hand_position"])
    # the calibration uses the other demos and says which one it skipped
    lines = []
    result = run_calibration(data, "baxter_left", out=lines.append)
    assert result.n_demos == 3 and result.skipped == [f"pincer/{first.parent.name}"]
    assert f"skipped 1 demos without a recorded end-point: pincer/{first.parent.name}" in lines[0]


def robot_ee(robot, q):
    from ipromp_pin.robot import ee_positions

    return ee_positions(robot, q)


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("column", "value", "field"),
    [
        ("field.jointStates.position4", "100", "jointStates.position/left_s0"),
        ("field.jointStates.position3", "1e300", "jointStates.position/left_e1"),
        ("field.emgStates.ch2", "1e300", "emgStates/emg2"),
        ("field.emgStates.ch2", "-3", "emgStates/emg2"),
        ("field.imuStates.orientation.w", "49152", "imuStates.orientation"),
        ("field.imuStates.linear_acceleration.x", "1e9", "imuStates.linear_acceleration"),
        ("field.endpointStates.pose.position.x", "1e300", "endpointStates.pose.position"),
    ],
)
def test_implausible_multimodal_values_are_refused(tmp_path, handover2017_dir, column, value, field):
    data = _copy_multimodal(handover2017_dir, tmp_path / "mm", per_task=1)
    first = sorted(data.glob("*/csv/*/multiModal_states.csv"))[0]
    _edit_csv(first, _set_columns(column, value, slice(20, 21)))
    with pytest.raises(DataError, match="implausible") as info:
        read_demo(first)
    assert field in info.value.field and str(first) == info.value.source


@pytest.mark.realdata
def test_multimodal_all_zero_emg_is_refused(tmp_path, handover2017_dir):
    data = _copy_multimodal(handover2017_dir, tmp_path / "mm", per_task=1)
    first = sorted(data.glob("*/csv/*/multiModal_states.csv"))[0]
    _edit_csv(first, _set_columns("field.emgStates.ch", "0"))
    with pytest.raises(DataError, match="every EMG channel is constant"):
        read_demo(first)


def _copy_chen(src: Path, dst: Path) -> Path:
    for task in ("tape_hold", "aluminum_hold"):
        stamps = sorted({p.name[:19] for p in (src / task / "csv").glob("*-myo_raw_emg_pub.csv")})[:2]
        (dst / task / "csv").mkdir(parents=True)
        for s in stamps:
            for p in (src / task / "csv").glob(s + "-*.csv"):
                shutil.copy(p, dst / task / "csv" / p.name)
    return dst


@pytest.mark.realdata
@pytest.mark.parametrize("how", ["no messages", "stamps 0", "no file"])
def test_chen2017_demo_without_end_point_loads(tmp_path, chen2017_dir, how):
    data = _copy_chen(chen2017_dir, tmp_path / "ch")
    ep = sorted(data.glob("*/csv/*-robot-limb-left-endpoint_state.csv"))[0]
    prefix = ep.parent / ep.name[:19]
    reference = read_demo(prefix)
    if how == "no messages":
        ep.write_text(ep.read_text().splitlines()[0] + "\n")
    elif how == "stamps 0":
        _edit_csv(ep, _set_columns(".header.stamp", "0"))
    else:
        ep.unlink()
    demo = read_demo(prefix)
    assert "endpoint_pose" not in demo.extras
    # the other streams are aligned as before (the end-point only narrowed the overlap, if at all)
    n = min(demo.n_samples, reference.n_samples)
    assert abs(demo.n_samples - reference.n_samples) <= 3
    assert np.abs(demo.groups["robot"][:n] - reference.groups["robot"][:n]).max() < 0.05
    result = run_calibration(data, "baxter_left", out=None)
    assert result.skipped == [f"{prefix.parent.parent.name}/{prefix.name}"] and result.n_demos == 3


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("suffix", "column", "value", "field"),
    [
        ("myo_raw_emg_pub", ".ch1", "1e300", ".ch0-7/emg1"),
        ("myo_raw_emg_pub", ".ch1", "-5", ".ch0-7/emg1"),
        ("myo_raw_imu_pub", ".quat0", "100000", ".quat0-3"),
        ("myo_raw_imu_pub", ".acc0", "1e300", ".acc0-2"),
        ("robot-limb-left-endpoint_state", ".pose.position.x", "1e300", ".pose.position"),
    ],
)
def test_implausible_chen2017_values_are_refused(tmp_path, chen2017_dir, suffix, column, value, field):
    data = _copy_chen(chen2017_dir, tmp_path / "ch")
    path = sorted(data.glob(f"*/csv/*-{suffix}.csv"))[0]

    def change(rows):
        rows[20][rows[0].index(column)] = value

    _edit_csv(path, change)
    with pytest.raises(DataError, match="implausible") as info:
        read_demo(path)
    assert info.value.field.startswith(field) and info.value.source == str(path)


@pytest.mark.realdata
@pytest.mark.parametrize("value", ["1e300", "50.0", "-7"])
def test_implausible_chen2017_joint_anywhere_in_the_file_is_refused(tmp_path, chen2017_dir, value):
    # the first arm message lies before the streams' overlap: it is checked all the same
    data = _copy_chen(chen2017_dir, tmp_path / "ch")
    path = sorted(data.glob("*/csv/*-robot-joint_states.csv"))[0]

    def change(rows):
        i = rows[0].index(".position")
        for r in rows[1:]:
            if r[i].count(",") > 5:
                parts = r[i].strip("()").split(",")
                parts[4] = value  # left_s0 (names are alphabetical)
                r[i] = "(" + ",".join(parts) + ")"
                return

    _edit_csv(path, change)
    with pytest.raises(DataError, match="implausible joint angle") as info:
        read_demo(path)
    assert info.value.field == ".position/left_s0"
