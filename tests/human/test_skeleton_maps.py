"""Any skeleton, never a silent stand-in (issue 36, item 4): the body model reads a recording's tracked
skeleton through the robot settings' skeleton map (``[human] skeleton``, ``[human.skeleton_map]``); a
recording whose skeleton the map does not cover is refused naming the frames it lacks, never judged
against the assumed human instead."""

from __future__ import annotations

import glob
import json
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError, RobotError
from ipromp_pin.human import SKELETON_PREFIX, HumanMotion
from ipromp_pin.human.body import ASSUMED_POSE_M
from ipromp_pin.human.separation import SeparationAnalyser
from ipromp_pin.readers import load_dataset, write_demo
from ipromp_pin.readers.multimodal import read_demo
from ipromp_pin.robot import ROBOTS_DIR, load_robot, load_robot_settings
from ipromp_pin.robot.human_settings import HumanSettings
from ipromp_pin.robot.skeleton_maps import SKELETONS, SkeletonMap

LEFT = ROBOTS_DIR / "baxter_left.toml"
RATE = 50.0
STAND = np.array([1.27, -0.26, 0.15])

OPENNI_TO_AZURE = {
    # OpenNI's labels are mirrored (its /left_* frames are the person's right side), Azure Kinect's
    # are the person's own: the same body point has the other side's name
    "/head_1": "/head",
    "/neck_1": "/neck",
    "/torso_1": "/spine_navel",
    "/left_shoulder_1": "/shoulder_right",
    "/right_shoulder_1": "/shoulder_left",
    "/left_elbow_1": "/elbow_right",
    "/right_elbow_1": "/elbow_left",
    "/left_hand_1": "/hand_right",
    "/right_hand_1": "/hand_left",
    "/left_hip_1": "/hip_right",
    "/right_hip_1": "/hip_left",
    "/left_knee_1": "/knee_right",
    "/right_knee_1": "/knee_left",
    "/left_foot_1": "/foot_right",
    "/right_foot_1": "/foot_left",
}
"""The handover_20171128 frames as an Azure Kinect recorder names the same points."""


def _renamed(demo: Demo, names: dict[str, str], drop: tuple[str, ...] = ()) -> Demo:
    """``demo`` with its skeleton extras renamed (``names``: old frame -> new), ``drop`` (new) removed."""
    extras = {}
    for key, value in demo.extras.items():
        if key.startswith(SKELETON_PREFIX):
            new = names[key[len(SKELETON_PREFIX) :]]
            if new in drop:
                continue
            key = SKELETON_PREFIX + new
        extras[key] = value
    return Demo(
        demo.task, demo.name, demo.source, demo.t, demo.groups, demo.channel_names, demo.missing, extras
    )


def _standing(n: int = 60) -> Demo:
    """A tracked human standing at the assumed pose (OpenNI frames), facing -x at :data:`STAND`."""
    t = np.arange(n) / RATE
    extras = {
        SKELETON_PREFIX + f: np.tile(STAND + np.array([-off[0], off[1], off[2]]), (n, 1))
        for f, off in ASSUMED_POSE_M.items()
    }
    names = {"emg": tuple(f"ch{i}" for i in range(8))}
    return Demo("task", "d0", "demo.csv", t, {"emg": np.zeros((n, 8))}, names, extras=extras)


def _azure() -> HumanSettings:
    return HumanSettings(skeleton=SKELETONS["azure_kinect"])


@pytest.fixture(scope="module")
def recorded(handover2017_dir: Path) -> Demo:
    path = sorted(glob.glob(str(handover2017_dir / "pincer" / "csv" / "*" / "multiModal_states.csv")))[0]
    return read_demo(path)


@pytest.mark.realdata
def test_renamed_frames_with_the_matching_map_give_the_same_separation(recorded):
    robot = load_robot("baxter_left")
    original = HumanMotion.from_demo(recorded, HumanSettings())
    azure = HumanMotion.from_demo(_renamed(recorded, OPENNI_TO_AZURE), _azure())
    assert original is not None and azure is not None and not azure.assumed
    assert azure.frames == original.frames and np.array_equal(
        azure.positions_m, original.positions_m, equal_nan=True
    )
    # the demonstrated robot motion against each body: the same numbers, the same sides named
    q = np.asarray(recorded.groups["robot"], dtype=float)
    qd = np.gradient(q, recorded.t, axis=0)
    a = SeparationAnalyser(robot).analyse(recorded.t, q, qd, original)
    b = SeparationAnalyser(robot).analyse(recorded.t, q, qd, azure)
    assert a.parts == b.parts and a.regions == b.regions
    for field in ("distance_m", "inflation_m", "approach_m_s", "protective_m", "speed_ratio"):
        assert np.array_equal(getattr(a, field), getattr(b, field), equal_nan=True), field
    assert np.isfinite(a.distance_m).all() and a.distance_m.min() < 1.0  # a real, nearby body


@pytest.mark.realdata
def test_a_recorded_skeleton_the_map_does_not_cover_is_refused_never_assumed(recorded):
    renamed = _renamed(recorded, OPENNI_TO_AZURE)
    with pytest.raises(DataError) as exc:
        HumanMotion.from_demo(renamed, HumanSettings())  # the OpenNI map on Azure names
    msg = str(exc.value)
    assert "\n" not in msg and recorded.source in msg and "skeleton map 'openni'" in msg
    for frame in ("/head_1", "/neck_1", "/torso_1", "/left_hand_1", "/right_knee_1"):
        assert frame in msg
    assert "/hand_right" in msg  # what the recording has instead
    # one joint missing from the recording: only that one is named
    with pytest.raises(DataError, match=r"lacks the frames /knee_left of skeleton map 'azure_kinect'"):
        HumanMotion.from_demo(_renamed(recorded, OPENNI_TO_AZURE, drop=("/knee_left",)), _azure())


def test_a_demo_without_any_skeleton_still_has_no_tracked_human_whatever_the_map():
    demo = _standing()
    bare = Demo(demo.task, demo.name, demo.source, demo.t, demo.groups, demo.channel_names)
    assert HumanMotion.from_demo(bare, HumanSettings()) is None
    assert HumanMotion.from_demo(bare, _azure()) is None


def test_a_joint_mapped_to_several_frames_is_their_mean():
    """A tracker without a neck frame (MediaPipe Pose): the neck is the mean of the two shoulders."""
    demo = _standing()
    extras = dict(demo.extras)
    neck = extras.pop(SKELETON_PREFIX + "/neck_1")
    extras[SKELETON_PREFIX + "/l_sh"] = neck + np.array([0.0, 0.1, 0.02])
    extras[SKELETON_PREFIX + "/r_sh"] = neck - np.array([0.0, 0.1, 0.02])
    frames = dict(SKELETONS["openni"].frames, neck=("/l_sh", "/r_sh"))
    settings = HumanSettings(skeleton=SkeletonMap("custom", frames, mirrored=True))
    shown = Demo(demo.task, demo.name, demo.source, demo.t, demo.groups, demo.channel_names, extras=extras)
    h = HumanMotion.from_demo(shown, settings)
    assert h is not None
    assert np.allclose(h.positions_m[:, h.frames.index("/neck_1")], neck, atol=1e-12)
    with pytest.raises(DataError, match="lacks the frames /neck_1 of skeleton map 'openni'"):
        HumanMotion.from_demo(shown, HumanSettings())


def _settings_with(tmp_path: Path, human_lines: str, tables: str = "") -> Path:
    """The left arm's settings with ``human_lines`` for its ``skeleton = "openni"`` and ``tables`` added."""
    shipped = 'skeleton = "openni"\n'
    assert shipped in LEFT.read_text()
    text = LEFT.read_text().replace(shipped, human_lines + "\n", 1) + "\n" + tables + "\n"
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return path


def _refused(path: Path, field: str) -> str:
    with pytest.raises(RobotError) as exc:
        load_robot_settings(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"{path}: field '{field}': "), msg
    return msg


def test_the_settings_choose_a_shipped_map_or_replace_its_joints(tmp_path):
    assert load_robot_settings(LEFT).human.skeleton == SKELETONS["openni"]
    chosen = load_robot_settings(_settings_with(tmp_path, 'skeleton = "azure_kinect"')).human.skeleton
    assert chosen == SKELETONS["azure_kinect"] and not chosen.mirrored
    edited = load_robot_settings(
        _settings_with(tmp_path, "", '[human.skeleton_map]\nneck = ["/l_sh", "/r_sh"]\nhead = "/nose"')
    ).human.skeleton
    assert edited.frames["neck"] == ("/l_sh", "/r_sh") and edited.frames["head"] == ("/nose",)
    assert edited.frames["torso"] == ("/torso_1",) and edited.mirrored  # the rest from 'openni'
    assert edited.body_frames()["/neck_1"] == ("/l_sh", "/r_sh")


@pytest.mark.parametrize(
    ("human_lines", "tables", "field", "hint"),
    [
        ("", '[human.skeleton_map]\nleft_elbw = "/elbow_left"', "human.skeleton_map.left_elbw", "left_elbow"),
        ("", "[human.skeleton_map]\nmirored = false", "human.skeleton_map.mirored", "mirrored"),
        ('skeleton = "azure"', "", "human.skeleton", "azure_kinect"),
        ('skeletn = "openni"', "", "human.skeletn", "skeleton"),
        ("", "[human.skeleton_map]\nhead = 3", "human.skeleton_map.head", "frame name"),
        ("", "[human.skeleton_map]\nhead = []", "human.skeleton_map.head", "non-empty"),
        ("", '[human.skeleton_map]\nmirrored = "no"', "human.skeleton_map.mirrored", "true or false"),
    ],
)
def test_an_unknown_or_malformed_map_key_is_refused(tmp_path, human_lines, tables, field, hint):
    assert hint in _refused(_settings_with(tmp_path, human_lines, tables), field)


AZURE_OF_ASSUMED = {f: OPENNI_TO_AZURE[f] for f in ASSUMED_POSE_M}


def _with_azure_skeleton(src: Path, dst: Path) -> Path:
    """The native dataset ``src`` with a tracked skeleton in every demo, its frames named as Azure
    Kinect names them (the assumed standing human of the Baxter settings)."""
    settings = load_robot_settings(LEFT).human
    for demo in load_dataset(src, format="native").all_demos():
        h = HumanMotion.assumed_human(settings, demo.t)
        extras = dict(demo.extras)
        for j, frame in enumerate(h.frames):
            extras[SKELETON_PREFIX + AZURE_OF_ASSUMED[frame]] = h.positions_m[:, j]
        out = Demo(demo.task, demo.name, demo.source, demo.t, demo.groups, demo.channel_names,
                   demo.missing, extras)  # fmt: skip
        write_demo(out, dst / demo.task / f"{demo.name}.npz")
    return dst


def test_the_command_refuses_an_uncovered_skeleton_before_training_and_plans_with_its_map(
    tiny, tmp_path, capsys
):
    ds = _with_azure_skeleton(tiny[0], tmp_path / "azure")
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--no-preview"]
    assert main([*args, "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    line = one_error_line(err)
    assert "field 'skeleton'" in line and "/head_1" in line and "skeleton map 'openni'" in line
    assert "[model]" not in err  # refused before any training
    robot = _settings_with(tmp_path, 'skeleton = "azure_kinect"')
    assert main([*args, "--robot", str(robot), "--out", str(tmp_path / "planned")]) in (0, 3)
    checks = json.loads((tmp_path / "planned" / "report.json").read_text())["feasibility"]["checks"]
    assert checks["human_clearance"]["human"] == "tracked"  # the recorded skeleton, not the assumed human
    assert checks["contact_speed"]["human"] == "tracked"
