"""``ipromp-pin place [DATASET] --robot NAME``: the suggested base placement of an arm in the
recordings' scene (issue 37, item 5), measured on the dataset's hand-over poses."""

from __future__ import annotations

import contextlib
import io
import re

import numpy as np
import pytest
from helpers_cli import one_error_line
from helpers_urdf import panda_out_of_reach

from ipromp_pin.app import main
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot, load_robot_settings
from ipromp_pin.robot.reachability import ReachTest, handover_poses
from ipromp_pin.robot.settings import ROBOTS_DIR

REACHED = re.compile(r"^(current|suggested) placement \(([^)]*)\) m, yaw (\S+) deg: (\d+)/(\d+) ")


def reached(out: str) -> dict[str, tuple[np.ndarray, float, int, int]]:
    """Placement (xyz [m], yaw [deg]) and poses reached / tried per printed line."""
    found = {}
    for line in out.splitlines():
        m = REACHED.match(line)
        if m:
            xyz = np.array([float(v) for v in m.group(2).split(",")])
            found[m.group(1)] = (xyz, float(m.group(3)), int(m.group(4)), int(m.group(5)))
    return found


@pytest.fixture(scope="module")
def panda_place(tmp_path_factory):
    written = tmp_path_factory.mktemp("place") / "panda_here.toml"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["place", "--robot", "panda", "--write", str(written)])
    return code, written, printed.getvalue()


def test_place_on_the_default_reaches_at_least_the_current_placement_s_poses(panda_place):
    code, written, out = panda_place
    lines = reached(out)
    _, _, cur, n = lines["current"]
    xyz, yaw, sug, n2 = lines["suggested"]
    assert n == n2 == len(make_synthetic_dataset().all_demos()) and sug >= cur
    assert "[placement]" in out and 'source = "baxter_left"' in out
    # the printed fraction is the reach at the written placement, measured again here
    settings = load_robot_settings(written)
    np.testing.assert_allclose(settings.placement.xyz_m, xyz, atol=5e-4)
    assert settings.placement.rpy_deg[2] == pytest.approx(yaw, abs=0.05)
    poses = handover_poses(load_robot("baxter_left"), make_synthetic_dataset().all_demos())
    again = ReachTest(settings).reach(poses)
    assert again is not None and again.n_reached == sug


def test_the_written_file_loads_as_the_arm_s_settings_with_only_its_placement_changed(panda_place):
    code, written, _ = panda_place
    assert code == 0
    here, shipped = load_robot_settings(written), load_robot_settings("panda")
    assert here.name == shipped.name and here.arm_joints == shipped.arm_joints
    assert (
        here.urdf_path == shipped.urdf_path and here.collision_max_step_rad == shipped.collision_max_step_rad
    )
    robot = load_robot(written)  # with its collision model: a placement the checks accept
    assert robot.n_joints == 7
    assert f"Suggested by `ipromp-pin place --robot panda --write {written}`" in written.read_text()


def test_a_placement_far_away_is_improved(tmp_path, capsys):
    far = panda_out_of_reach(tmp_path)
    assert main(["place", "--robot", str(far)]) == 0
    lines = reached(capsys.readouterr().out)
    assert lines["current"][2] == 0 and lines["suggested"][2] == lines["suggested"][3]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--robot", "no_such_arm"], "no_such_arm: robot settings file not found"),
        (["--robot", "baxter_left"], "has no [placement]"),
        (["{empty}", "--robot", "panda"], "no task sub-folders"),
        (
            ["--robot", "panda", "--write", str(ROBOTS_DIR / "panda.toml")],
            "shipped settings file is never changed",
        ),
    ],
)
def test_bad_inputs_are_one_line_errors_with_exit_2(tmp_path, capsys, args, message):
    before = (ROBOTS_DIR / "panda.toml").read_bytes()
    args = [str(tmp_path) if a == "{empty}" else a for a in args]
    assert main(["place", *args]) == 2
    assert message in one_error_line(capsys.readouterr().err)
    assert (ROBOTS_DIR / "panda.toml").read_bytes() == before
