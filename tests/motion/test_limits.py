"""Limit profiles: conservative from the settings, demonstrated from training demos, profile files."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import PipelineError, RobotError
from ipromp_pin.motion.limits import (
    conservative_profile,
    demo_peaks,
    demonstrated_profile,
    read_limit_profile,
)
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import DemoLimitRecipe, load_robot, load_robot_settings
from ipromp_pin.robot.settings import ROBOTS_DIR


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


@pytest.fixture(scope="module")
def demos():
    return make_synthetic_dataset(n_tasks=2, n_demos=6, seed=4).all_demos()


def test_demo_peaks_measure_a_known_motion(robot, demos):
    d = demos[0]
    t = d.t
    q = np.zeros((t.size, robot.n_joints))
    q[:, 0] = 0.3 * np.sin(2 * np.pi * 0.5 * t)  # peak velocity 0.3 pi, acceleration 0.3 pi^2
    names = {"robot": tuple(robot.joint_names)}
    demo = type(d)(task="x", name="x", source="x", t=t, groups={"robot": q}, channel_names=names)
    v, a, _ = demo_peaks([demo], window_s=0.34)[0][:, 0]
    assert v == pytest.approx(0.3 * np.pi, rel=0.01)
    assert a == pytest.approx(0.3 * np.pi**2, rel=0.03)


def test_demonstrated_profile_is_bounded_by_the_urdf_and_the_conservative_profile(robot, demos):
    cons = conservative_profile(robot)
    prof = demonstrated_profile(robot, demos, DemoLimitRecipe(percentile=90.0), "synthetic")
    lim = prof.limits
    peaks = demo_peaks(demos, 0.34)
    assert np.all(lim.velocity_rad_s <= robot.velocity_rad_s)
    np.testing.assert_allclose(lim.velocity_rad_s, np.minimum(np.percentile(peaks[:, 0], 90, axis=0), 1e9))
    assert np.all(lim.acceleration_rad_s2 >= cons.limits.acceleration_rad_s2)
    assert np.all(lim.jerk_rad_s3 >= cons.limits.jerk_rad_s3)
    np.testing.assert_array_equal(lim.lower_rad, cons.limits.lower_rad)  # positions: URDF with margin
    top = demonstrated_profile(robot, demos, DemoLimitRecipe(percentile=100.0))
    assert np.all(top.limits.velocity_rad_s >= lim.velocity_rad_s)
    assert "90th percentile" in prof.source and f"{len(demos)} training demos of synthetic" in prof.source


def _profile_text(**values: str) -> str:
    base = {
        "velocity_rad_s": "[0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]",
        "acceleration_rad_s2": "2.0",
        "jerk_rad_s3": "20",
    }
    base.update(values)
    return "\n".join(f"{k} = {v}" for k, v in base.items() if v is not None) + "\n"


def test_profile_file_round_trip_and_bad_values(robot, demos, tmp_path):
    prof = demonstrated_profile(robot, demos)
    path = tmp_path / "limits.toml"
    path.write_text(prof.to_toml())
    back = read_limit_profile(path, robot)
    np.testing.assert_allclose(back.limits.jerk_rad_s3, prof.limits.jerk_rad_s3, rtol=1e-5)
    assert back.name == "demonstrated" and back.source == prof.source
    path.write_text(_profile_text())
    assert read_limit_profile(path, robot).limits.acceleration_rad_s2.tolist() == [2.0] * 7
    for values, field in (
        ({"acceleration_rad_s2": "[-1, 2, 2, 2, 2, 2, 2]"}, "acceleration_rad_s2"),
        ({"jerk_rad_s3": "[nan, 20, 20, 20, 20, 20, 20]"}, "jerk_rad_s3"),
        ({"jerk_rad_s3": "0"}, "jerk_rad_s3"),
        ({"velocity_rad_s": "[9, 1, 1, 1, 1, 1, 1]"}, "velocity_rad_s"),  # above the URDF's 1.5 rad/s
        ({"velocity_rad_s": "[1, 1]"}, "velocity_rad_s"),
        ({"acceleration_rad_s2": None}, "acceleration_rad_s2"),
        ({"jerk": "1"}, "jerk"),
    ):
        path.write_text(_profile_text(**values))
        with pytest.raises(PipelineError, match=f"{path}: field '{field}'") as exc:
            read_limit_profile(path, robot)
        assert "\n" not in str(exc.value)
    with pytest.raises(PipelineError, match="limit profile not found"):
        read_limit_profile(tmp_path / "missing.toml", robot)


def test_settings_carry_the_demonstrated_recipe(tmp_path):
    s = load_robot_settings("baxter_left")
    assert 0 < s.demonstrated_limits.percentile <= 100 and s.demonstrated_limits.window_s > 0
    text = (ROBOTS_DIR / "baxter_left.toml").read_text()
    assert "[limits.demonstrated]" in text
    bad = text.replace("percentile = ", "percentile = -", 1)
    path = tmp_path / "robot.toml"
    path.write_text(bad)
    with pytest.raises(RobotError, match="field 'limits.demonstrated.percentile'"):
        load_robot_settings(path)
