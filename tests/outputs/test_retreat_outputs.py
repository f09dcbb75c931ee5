"""The retreat in ``run``'s outputs (outputs/retreat_files.py, staging, rosbag, report, preview):
the second segment round-trips, the first stays readable, ``--no-retreat`` removes it, a failing
retreat check fails the run with exit 3."""

from __future__ import annotations

import contextlib
import io
import json

import jsonschema
import numpy as np
import pytest
from helpers_cli import PIPELINE, one_error_line, run_tiny

from ipromp_pin import app as cli
from ipromp_pin.app.config import load_pipeline
from ipromp_pin.app.session import plan_session, prepare_session
from ipromp_pin.outputs.preview_content import preview_content
from ipromp_pin.outputs.retreat_files import read_retreat_json
from ipromp_pin.outputs.rosbag import JOINT_STATE, TOPIC_RETREAT
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv, read_trajectory_json
from ipromp_pin.schemas import load_schema

# a received object with its centre of mass far out: light enough at the tiny run's hand-over (about
# 80 % of an effort limit), too heavy for gravity alone at the retreat's target (about 120 % at left_w0)
HEAVY_RETREAT = """
[{task}]
mass_kg = 1.7
com_m = [0.9, 0.0, 0.0]
holder = "robot_receives"
retreat = {{ joints_rad = [-1.25, 0.65, 1.72, 1.51, 1.57, 1.42, 1.49], dwell_s = 0.2 }}
"""


@pytest.fixture(scope="module")
def run_out(tmp_path_factory, tiny):
    out = tmp_path_factory.mktemp("retreat") / "out"
    log = io.StringIO()
    with contextlib.redirect_stdout(log):
        assert run_tiny(tiny, out, "--task", "rod") == 0  # the rod is received: the retreat carries it
    (out.parent / "log.txt").write_text(log.getvalue())
    return out


def test_the_retreat_is_the_second_segment_of_the_files(run_out):
    main = read_trajectory_json(run_out / "trajectory.json")  # the existing reader: the approach
    np.testing.assert_array_equal(main.q, read_trajectory_csv(run_out / "trajectory.csv").q)
    retreat = read_retreat_json(run_out / "trajectory.json")
    csv = read_trajectory_csv(run_out / "retreat.csv")
    assert retreat is not None and retreat.n_samples == csv.n_samples > 50
    np.testing.assert_allclose(retreat.t_s, csv.t_s, atol=1e-9)
    np.testing.assert_array_equal(retreat.q, csv.q)
    assert retreat.t_s[0] == pytest.approx(main.t_s[-1])  # one clock: from the hand-over ...
    np.testing.assert_allclose(retreat.q[0], main.q[-1], atol=1e-12)
    np.testing.assert_allclose(retreat.q[-1], main.q[0], atol=1e-12)  # ... back to the start (shipped)
    doc = json.loads((run_out / "trajectory.json").read_text())
    member = doc["retreat"]
    assert member["target"] == "start" and member["dwell_s"] == 0.5
    assert member["start_s"] == pytest.approx(main.t_s[-1])
    assert len(member["message"]["points"][5]["effort"]) == 7  # the torques, as the approach's


def test_the_report_has_a_retreat_section(run_out):
    report = json.loads((run_out / "report.json").read_text())
    jsonschema.Draft202012Validator(load_schema("report")).validate(report)
    r = report["retreat"]
    assert r["passed"] and report["passed"] and r["target"]["to"] == "start"
    assert r["payload"] is not None and r["payload"]["holder"] == "robot_receives"  # rod: received
    assert set(r["checks"]) == {  # the hand-over checks do not apply after the hand-over
        "speed_limits",
        "joint_limits",
        "self_collision",
        "human_clearance",
        "contact_speed",
        "joint_torques",
    }
    assert r["duration_s"] > r["dwell_s"] and r["stage_ms"]["total"] > 0
    assert report["files"]["retreat_csv"].endswith("retreat.csv")
    assert "Retreat to the start configuration: PASSED" in (run_out / "report.txt").read_text()
    log = (
        run_out.parent / "log.txt"
    ).read_text()  # the verdict once in the log: a progress line, the summary
    assert log.count("Retreat to the start configuration: PASSED") == 1 and "[retreat] pass;" in log


def test_the_bag_carries_the_retreat(run_out):
    from rosbags.highlevel import AnyReader

    with AnyReader([run_out / "rosbag"]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        states = [c for c in reader.connections if c.msgtype == JOINT_STATE]
    main = read_trajectory_csv(run_out / "trajectory.csv")
    retreat = read_trajectory_csv(run_out / "retreat.csv")
    assert counts[TOPIC_RETREAT] == 1
    assert sum(c.msgcount for c in states) == main.n_samples + retreat.n_samples - 1


def test_no_retreat_leaves_it_out_and_removes_an_earlier_one(tmp_path, tiny):
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--no-rosbag") == 0
    assert (out / "retreat.csv").exists()
    assert run_tiny(tiny, out, "--no-rosbag", "--no-retreat") == 0
    assert not (out / "retreat.csv").exists()
    assert read_retreat_json(out / "trajectory.json") is None
    assert json.loads((out / "report.json").read_text())["retreat"] is None


def test_a_failing_retreat_check_fails_the_run_with_exit_3(tmp_path, tiny, capsys):
    objects = tmp_path / "objects.toml"
    objects.write_text(HEAVY_RETREAT.format(task="rod") + HEAVY_RETREAT.format(task="wrench"))
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--objects", str(objects), "--no-rosbag") == cli.EXIT_CHECKS_FAILED
    assert "retreat.joint_torques" in one_error_line(capsys.readouterr().err)
    report = json.loads((out / "report.json").read_text())
    assert report["feasibility"]["passed"] and not report["passed"]  # the approach passed
    assert "joint_torques" in report["retreat"]["failures"]
    assert "slowing down cannot help" in report["retreat"]["checks"]["joint_torques"]["reason"]
    assert not (out / "trajectory.csv").exists() and not (out / "retreat.csv").exists()
    # written on request, marked like the approach
    assert run_tiny(tiny, out, "--objects", str(objects), "--no-rosbag", "--allow-failing-checks") == 3
    assert (out / "retreat.csv").read_text().startswith("# ipromp_pin: checks FAILED (retreat.")


def test_the_preview_animates_the_retreat_after_the_hand_over(tmp_path, tiny):
    cfg = load_pipeline(PIPELINE, dataset=tiny[0], load_model=tiny[1], out_dir=tmp_path)
    session = prepare_session(cfg, log=lambda _m: None)
    planned = plan_session(session, lambda _m: None)
    result, retreat = planned.approach, planned.retreat
    assert retreat is not None
    alone = preview_content(result, session.robot, session.demo)
    both = preview_content(result, session.robot, session.demo, retreat=retreat)
    n = result.trajectory.n_samples
    assert both.t_s.size == n + retreat.trajectory.n_samples - 1 and alone.t_s.size == n
    np.testing.assert_allclose(both.q[-1], retreat.q_target, atol=1e-12)
    assert both.t_s[-1] == pytest.approx(result.trajectory.end_s + retreat.duration_s)
    assert both.t_s[0] == pytest.approx(result.start_s)  # the human's clock
    names = [c.name for c in both.checks]
    assert "retreat joint_torques" in names and "retreat self_collision" in names
    assert any(note.startswith("Retreat to") for note in both.notes)


def test_an_unreachable_retreat_position_exits_2_and_leaves_the_folder_as_it_was(tmp_path, tiny, capsys):
    objects = tmp_path / "objects.toml"
    entry = "mass_kg = 0.4\nholder = 'robot_receives'\nretreat = { position_m = [1.5, 0.9, 0.8] }\n"
    objects.write_text(f"[rod]\n{entry}[wrench]\n{entry}")
    out = tmp_path / "out"
    out.mkdir()
    (out / "trajectory.csv").write_text("an earlier run's file")
    assert run_tiny(tiny, out, "--objects", str(objects), "--no-rosbag") == 2
    line = one_error_line(capsys.readouterr().err)
    assert (
        "retreat.position_m': not reachable with the hand-over orientation" in line and str(objects) in line
    )
    assert sorted(p.name for p in out.iterdir()) == ["trajectory.csv"]
    assert (out / "trajectory.csv").read_text() == "an earlier run's file"
