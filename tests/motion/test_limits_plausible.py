"""Limit-profile files within the robot settings' plausible ranges and below what the settings allow
(issue 24, item 2): an absurd acceleration or jerk is refused in one line, never used."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.exceptions import PipelineError
from ipromp_pin.motion.limits import PROFILE_CEILING_FACTOR, demonstrated_profile, read_limit_profile
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _write(path, velocity="1.0", acceleration="2.0", jerk="20.0"):
    path.write_text(
        f"velocity_rad_s = {velocity}\nacceleration_rad_s2 = {acceleration}\njerk_rad_s3 = {jerk}\n"
    )
    return path


@pytest.mark.parametrize(
    ("values", "field", "problem"),
    [
        ({"acceleration": "1e-9"}, "acceleration_rad_s2", "implausible value 1e-09"),
        ({"acceleration": "5e-4"}, "acceleration_rad_s2", "implausible value"),
        ({"acceleration": "1e6"}, "acceleration_rad_s2", "implausible value 1e+06"),
        ({"acceleration": "[2, 2, 2, 2, 2, 2, 1e5]"}, "acceleration_rad_s2", "implausible value 100000"),
        ({"acceleration": "20.5"}, "acceleration_rad_s2", "above what the robot settings allow"),
        ({"acceleration": "[2, 2, 2, 30, 2, 2, 2]"}, "acceleration_rad_s2", "30 for left_e1 is above"),
        ({"jerk": "1e9"}, "jerk_rad_s3", "implausible value 1e+09"),
        ({"jerk": "1e-3"}, "jerk_rad_s3", "implausible value 0.001"),
        ({"jerk": "201"}, "jerk_rad_s3", "above what the robot settings allow"),
        ({"velocity": "1e-4"}, "velocity_rad_s", "implausible value 0.0001"),
    ],
)
def test_implausible_profile_values_are_refused_in_one_line(robot, tmp_path, values, field, problem):
    path = _write(tmp_path / "limits.toml", **values)
    with pytest.raises(PipelineError, match=f"{path}: field '{field}'") as exc:
        read_limit_profile(path, robot)
    assert problem in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize(
    ("acceleration", "jerk"), [("1e-3", "1e-2"), ("20", "200"), ("[1, 2, 3, 4, 5, 6, 7]", "81.4")]
)
def test_plausible_profile_values_are_kept(robot, tmp_path, acceleration, jerk):
    prof = read_limit_profile(_write(tmp_path / "limits.toml", acceleration=acceleration, jerk=jerk), robot)
    assert np.all(
        prof.limits.acceleration_rad_s2 <= robot.settings.acceleration_rad_s2 * PROFILE_CEILING_FACTOR
    )


def test_demonstrated_profile_stays_below_the_ceiling_and_rereads(robot, tmp_path):
    demos = make_synthetic_dataset(n_tasks=1, n_demos=4, seed=2).all_demos()
    demos = [dataclasses.replace(d, t=d.t / 30.0) for d in demos]  # 30x faster: implausible peaks
    prof = demonstrated_profile(robot, demos)
    ceiling = robot.settings.acceleration_rad_s2 * PROFILE_CEILING_FACTOR
    assert np.all(prof.limits.acceleration_rad_s2 <= ceiling + 1e-9)
    assert np.any(prof.limits.acceleration_rad_s2 >= ceiling - 1e-9)  # the cap took effect
    path = tmp_path / "limits.toml"
    path.write_text(prof.to_toml())
    read_limit_profile(path, robot)  # what replay writes, it reads back


@pytest.mark.parametrize("acceleration", ["1e-9", "1e6"])
@pytest.mark.parametrize("command", ["replay", "evaluate"])
def test_replay_and_evaluate_refuse_the_profile_before_computing(
    tiny, tmp_path, capsys, acceleration, command
):
    ds, model = tiny
    path = _write(
        tmp_path / "limits.toml", acceleration=acceleration, jerk="1e9" if acceleration == "1e6" else "20"
    )
    if command == "replay":
        args = ["replay", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--no-preview"]
    else:
        args = ["evaluate", str(ds), "--closed-loop"]
    code = main(
        [*args, "--limits", str(path)] + (["--out", str(tmp_path / "out")] if command == "replay" else [])
    )
    assert code == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"{path}: field 'acceleration_rad_s2': implausible value" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("text", "field", "hint"),
    [
        ("acceleration_rad_s = 2.0", "acceleration_rad_s", "acceleration_rad_s2"),
        ("veloctiy_rad_s = 1.0", "veloctiy_rad_s", "velocity_rad_s"),
        ("[limits]\njerk_rad_s3 = 20.0", "limits", None),
    ],
)
def test_an_unknown_profile_key_is_refused_with_a_suggestion(robot, tmp_path, text, field, hint):
    path = tmp_path / "limits.toml"
    path.write_text("velocity_rad_s = 1.0\nacceleration_rad_s2 = 2.0\njerk_rad_s3 = 20.0\n" + text + "\n")
    with pytest.raises(PipelineError) as exc:
        read_limit_profile(path, robot)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: field '{field}': unknown key") and "\n" not in msg, msg
    if hint:
        assert f"did you mean '{hint}'?" in msg
