"""A robot whose joints the demos do not record is refused before training, in one line saying what
it needs (issue 24, item 14)."""

from __future__ import annotations

import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.promp import IProMP


@pytest.mark.parametrize(
    "robot", ["baxter_right"]
)  # panda: placed in the scene, retargeted (test_run_other_arm.py)
@pytest.mark.parametrize("data", ["synthetic", "tiny"])
@pytest.mark.parametrize("command", ["run", "replay"])
def test_a_robot_the_demos_were_not_recorded_on_is_refused_before_training(
    tiny, tmp_path, capsys, monkeypatch, robot, data, command
):
    def no_training(*args, **kwargs):
        raise AssertionError("trained although the robot cannot use the demos")

    monkeypatch.setattr(IProMP, "fit", no_training)
    args = [command, str(PIPELINE), "--robot", robot, "--out", str(tmp_path / "out"), "--no-preview"]
    if data == "tiny":
        args += ["--dataset", str(tiny[0])]
    assert main(args) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"robot '{robot}' needs demonstrations recorded with its own joints" in line
    assert "use --robot baxter_left" in line
    assert not (tmp_path / "out" / "trajectory.csv").exists()
