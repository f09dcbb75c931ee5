"""Channel-group specifications: a new sensor group through the specification alone.

A fake grip-pressure bulb (one channel in [kPa], its own CSV reader) is registered with one
:func:`register_group` call; the model, the plausibility checks, the native resampling and the
rosbag writer then handle it without any other change.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.data import ROBOT, Dataset, Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.motion.timing import JointLimits, time_path
from ipromp_pin.outputs.rosbag import BagContent, human_topic, write_rosbag2
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.native import resample_demo
from ipromp_pin.readers.plausibility import check_demo
from ipromp_pin.readers.streams import CsvTable
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.signals.checks import RangeCheck
from ipromp_pin.signals.groups import (
    DEFAULT_LOG_GROUPS,
    ChannelGroup,
    RosMessage,
    group_spec,
    group_unit,
    is_registered,
    register_group,
    unregister_group,
)
from ipromp_pin.signals.preprocess import resample

FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"


def _fluid_pressure(types, header, label, values, names):
    # sensor_msgs/FluidPressure holds pascals
    return types[FLUID_PRESSURE](header=header, fluid_pressure=float(values[0]) * 1e3, variance=0.0)


PRESSURE = ChannelGroup(
    "pressure",
    "kPa",
    interpolation="previous",
    check=RangeCheck(0.0, 300.0, "kPa"),
    ros_message=RosMessage(FLUID_PRESSURE, _fluid_pressure),
    channels=("p",),
    n_channels=1,
)


@pytest.fixture
def pressure_group():
    register_group(PRESSURE, replace=True)
    yield PRESSURE
    unregister_group("pressure")


# ---------------------------------------------------------------- the fake sensor and its reader
def write_pressure_csv(path: Path, demo: Demo, rate_hz: float = 20.0) -> Path:
    """What the bulb records during ``demo``: the grip tightens with the EMG activity, in [kPa]."""
    t = np.arange(-0.1, demo.t[-1] + 0.2, 1.0 / rate_hz)
    activity = np.interp(t, demo.t, demo.groups["emg"].mean(axis=1))
    kpa = 101.3 + 0.05 * activity
    path.write_text(
        "time_s,pressure_kpa\n" + "".join(f"{a:.4f},{b:.6f}\n" for a, b in zip(t, kpa, strict=True))
    )
    return path


def read_pressure(path: Path, demo: Demo) -> Demo:
    """The bulb's CSV resampled onto the demo's grid (interpolation of the group's specification)."""
    table = CsvTable(path)
    t, kpa = table.numbers(["time_s"])[:, 0], table.numbers(["pressure_kpa"])
    spec = group_spec("pressure")
    values = resample(t, kpa, demo.t, spec.raw_kind)
    return dataclasses.replace(
        demo,
        groups={**demo.groups, "pressure": values},
        channel_names={**demo.channel_names, "pressure": spec.channels},
    )


@pytest.fixture
def pressure_dataset(pressure_group, tmp_path) -> Dataset:
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    demos = {
        task: [read_pressure(write_pressure_csv(tmp_path / f"{d.name}.csv", d), d) for d in items]
        for task, items in ds.demos.items()
    }
    return Dataset(ds.root, demos)


# ------------------------------------------------------------------------------------- tests
def test_built_in_groups_keep_their_units_checks_and_log_default():
    assert group_unit(ROBOT) == "rad" and group_unit("orientation") == "unitless"
    assert group_unit("emg") == "Myo EMG units" and group_unit("acc") == "g"
    assert group_unit("/left_hand_1") == "m" and group_unit("nothing_known") == ""
    assert DEFAULT_LOG_GROUPS == ("emg",) and IProMP(["orientation"]).log_groups == ("emg",)
    assert group_spec("/right_hand_1").ros_message.msgtype == "geometry_msgs/msg/PointStamped"
    assert group_spec("orientation").interpolation_kind(4) == "quaternion"
    assert group_spec("orientation").interpolation_kind(3) == "linear"
    with pytest.raises(DataError, match="already registered"):
        register_group(ChannelGroup("emg"))


def test_unknown_group_gets_the_generic_check_with_a_clear_message():
    ds = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=1)
    d = ds.all_demos()[0]
    assert not is_registered("mystery")
    v = np.zeros((d.n_samples, 2))
    check_demo(
        dataclasses.replace(
            d, groups={**d.groups, "mystery": v}, channel_names={**d.channel_names, "mystery": ("m0", "m1")}
        )
    )
    v[3, 1] = 1e300
    bad = dataclasses.replace(
        d, groups={**d.groups, "mystery": v}, channel_names={**d.channel_names, "mystery": ("m0", "m1")}
    )
    with pytest.raises(DataError) as err:
        check_demo(bad)
    msg = str(err.value)
    assert "mystery/m1" in msg and "no channel-group specification" in msg and "\n" not in msg


def test_a_new_group_through_the_specification_alone(pressure_dataset, tmp_path):
    assert is_registered("pressure") and group_unit("pressure") == "kPa"
    demos = pressure_dataset.all_demos()
    for d in demos:  # plausible values pass
        check_demo(d)

    # trains and predicts with the new group observed
    model = IProMP(["orientation", "pressure"], n_basis=9).fit(pressure_dataset)
    test = demos[1]
    pred = model.predict(test.head(0.5, ["orientation", "pressure"]))
    assert pred.q_mean.shape[1] == 7 and np.all(np.isfinite(pred.q_mean))
    assert "pressure" in pred.human_mean and pred.human_mean["pressure"].shape[1] == 1

    # a bad value is refused, in one line naming the group and its unit
    v = test.groups["pressure"].copy()
    v[7, 0] = 4000.0
    with pytest.raises(DataError) as err:
        check_demo(dataclasses.replace(test, groups={**test.groups, "pressure": v}))
    msg = str(err.value)
    assert "pressure/p" in msg and "kPa" in msg and "4000" in msg and "\n" not in msg

    # the native resampling uses the group's interpolation (held, not interpolated)
    step = test.groups["pressure"].copy()
    step[: step.shape[0] // 2] = 100.0
    step[step.shape[0] // 2 :] = 200.0
    held = resample_demo(dataclasses.replace(test, groups={**test.groups, "pressure": step}), 37.0)
    assert set(np.unique(held.groups["pressure"])) <= {100.0, 200.0}

    # the bag carries it as its specification's message type
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    limits = JointLimits.from_robot(load_robot("baxter_left"))
    traj = time_path(pred.q_mean[::5], limits, rate_hz=100.0)[0]
    obs = test.head(0.5, ["orientation", "pressure"])
    pose = np.array([0.8, -0.3, 0.2, 0.0, 0.6, 0.0, 0.8])
    folder = write_rosbag2(BagContent(traj, float(obs.t[-1]), pose, "base", obs), tmp_path / "bag")
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(folder) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        msgs = [
            store.deserialize_cdr(raw, c.msgtype)
            for c, _, raw in reader.messages()
            if c.topic == human_topic("pressure")
        ]
    assert types[human_topic("pressure")] == FLUID_PRESSURE
    assert types[human_topic("orientation")] == "geometry_msgs/msg/QuaternionStamped"
    assert len(msgs) == obs.n_samples
    np.testing.assert_allclose([m.fluid_pressure for m in msgs], obs.groups["pressure"][:, 0] * 1e3)
