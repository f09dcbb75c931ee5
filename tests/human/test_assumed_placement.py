"""The assumed human of the robot settings (``[human.assumed]``) against the robot's fixed links
(issue of 2026-12-04, round 3): a human placed inside the pedestal, the torso or the other arm is
refused naming the parts that intersect; the shipped placements pass."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from helpers_cli import ROBOT_FILE, one_error_line, run_tiny

from ipromp_pin.exceptions import RobotError
from ipromp_pin.human.placement import assumed_human_overlaps, check_assumed_human
from ipromp_pin.robot import load_robot


def _placed(tmp_path: Path, torso: str, facing: str = "180.0") -> Path:
    text = re.sub(r"^torso_m = .*$", f"torso_m = {torso}", ROBOT_FILE.read_text(), count=1, flags=re.M)
    text = re.sub(r"^facing_deg = .*$", f"facing_deg = {facing}", text, count=1, flags=re.M)
    path = tmp_path / "placed.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["baxter_left", "baxter_right", "panda"])
def test_the_shipped_placements_clear_the_fixed_links(name):
    robot = load_robot(name)
    assert assumed_human_overlaps(robot) == []
    check_assumed_human(robot)


@pytest.mark.parametrize(
    ("torso", "link"),
    [
        ("[0.0, 0.0, -0.45]", "pedestal"),  # standing inside the pedestal
        ("[0.05, 0.0, 0.35]", "torso"),  # inside the robot's torso
    ],
)
def test_a_human_inside_the_robot_is_refused_naming_the_parts(tmp_path, torso, link):
    path = _placed(tmp_path, torso)
    robot = load_robot(path, cache=False)
    overlaps = assumed_human_overlaps(robot)
    assert any(o.link == link for o in overlaps), overlaps
    assert all(o.depth_m > 0 for o in overlaps)
    with pytest.raises(RobotError) as exc:
        check_assumed_human(robot)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: field 'human.assumed.torso_m': ") and "\n" not in msg
    assert link in msg and "chest" in msg, msg


def test_a_human_against_the_other_arm_is_refused(tmp_path):
    robot = load_robot("baxter_left")
    # the right arm's forearm at its held pose, in the base frame: put the assumed chest there
    import pinocchio as pin

    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.q_neutral)
    p = data.oMf[robot.model.getFrameId("right_lower_forearm")].translation
    path = _placed(tmp_path, f"[{p[0]:.4f}, {p[1]:.4f}, {p[2] - 0.1:.4f}]")
    overlaps = assumed_human_overlaps(load_robot(path, cache=False))
    assert any(o.link.startswith("right_") for o in overlaps), overlaps


def test_run_refuses_a_human_inside_the_pedestal_in_one_line(tmp_path, tiny, capsys):
    path = _placed(tmp_path, "[0.0, 0.0, -0.45]")
    assert run_tiny(tiny, tmp_path / "out", "--robot", str(path)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "human.assumed.torso_m" in line and "pedestal" in line
    assert not (tmp_path / "out").exists()
