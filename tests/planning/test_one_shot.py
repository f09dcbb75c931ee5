"""The one-shot plan's model/robot check: the model's joints must be the robot's, matched by name
(ipromp_pin.planning.one_shot)."""

from __future__ import annotations

import pytest
from helpers_cli import PIPELINE, one_error_line, run_tiny

from ipromp_pin.app import main
from ipromp_pin.exceptions import ModelError
from ipromp_pin.planning.one_shot import check_model_joints
from ipromp_pin.promp import IProMP
from ipromp_pin.robot import load_robot


def test_model_joints_must_be_the_robots(tmp_path, tiny, capsys):
    model = IProMP.load(tiny[1])
    check_model_joints(model, load_robot("baxter_left"))
    with pytest.raises(ModelError, match=r"predicts joints \['left_s0'.*moves \['right_s0'"):
        check_model_joints(model, load_robot("baxter_right"))
    out = tmp_path / "out"
    # recordings are read by the robot's joint names: the left-arm demos have no right_s0
    assert run_tiny(tiny, out, "--robot", "baxter_right") == 2
    assert "field 'right_s0': unknown joint name" in one_error_line(capsys.readouterr().err)
    # the synthetic demos are left-arm demos too, but with --model the model's joints are checked
    argv = ["run", str(PIPELINE), "--model", str(tiny[1]), "--robot", "baxter_right", "--out", str(out)]
    assert main(argv) == 2
    assert "robot 'baxter_right' moves ['right_s0'" in one_error_line(capsys.readouterr().err)
    assert not out.exists()
