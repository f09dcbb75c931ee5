"""End-to-end pipeline: synthetic default and a real demo, outputs re-load, bad definitions fail clearly;
failing checks exit 3 without trajectory files, a failing write or save loses no earlier file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import ROBOT_FILE, one_error_line, run_tiny, without_uncertainty

from ipromp_pin import app as cli
from ipromp_pin import preview as preview_module
from ipromp_pin.app import main
from ipromp_pin.app.config import load_pipeline, resolve_pipeline_path
from ipromp_pin.exceptions import PipelineError
from ipromp_pin.motion.trajectory import JointLimits
from ipromp_pin.outputs import staging
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv, read_trajectory_json
from ipromp_pin.plans import files as plan_files
from ipromp_pin.promp import IProMP
from ipromp_pin.robot import load_robot
from ipromp_pin.shipped import PIPELINES_DIR

PIPELINE = Path(__file__).resolve().parents[2] / "pipelines" / "baxter_handover.toml"


def _check_outputs(out: Path) -> dict:
    report = json.loads((out / "report.json").read_text())
    csv_traj = read_trajectory_csv(out / "trajectory.csv")
    json_traj = read_trajectory_json(out / "trajectory.json")
    np.testing.assert_allclose(csv_traj.q, json_traj.q, atol=1e-9)
    np.testing.assert_allclose(csv_traj.t_s, json_traj.t_s, atol=1e-9)
    robot = load_robot("baxter_left")
    limits = JointLimits.from_robot(robot)
    # every sample inside the position and velocity limits
    assert np.all(csv_traj.q >= robot.lower_rad - 1e-9) and np.all(csv_traj.q <= robot.upper_rad + 1e-9)
    assert np.all(np.abs(csv_traj.qd) <= limits.velocity_rad_s * (1 + 1e-6))
    # starts and ends at rest
    assert np.allclose(csv_traj.qd[-1], 0.0, atol=1e-6) and np.allclose(csv_traj.qd[0], 0.0, atol=1e-6)
    assert set(report["posterior"]) and abs(sum(report["posterior"].values()) - 1.0) < 1e-9
    assert report["recognised_task"] == max(report["posterior"], key=report["posterior"].get)
    checks = report["feasibility"]["checks"]
    for name in ("joint_limits", "self_collision", "workspace"):  # the planned hand-overs are feasible
        assert checks[name]["status"] == "pass", checks[name]["reason"]
    failed = [n for n, c in checks.items() if c["required"] and c["status"] == "fail"]
    assert report["feasibility"]["failures"] == failed
    assert report["passed"] == (not failed and report["trajectory"]["passed"])
    # one clock: every check's time is a sample of the written trajectory
    times = [c["t_s"] for c in checks.values() if c.get("t_s") is not None]
    assert len(times) >= 4, checks
    for t in times:
        assert np.min(np.abs(csv_traj.t_s - t)) < 1e-6, (t, csv_traj.t_s[[0, -1]])
    assert report["arrival"]["robot_start_s"] == pytest.approx(csv_traj.t_s[0], abs=1e-6)
    assert report["arrival"]["robot_s"] == pytest.approx(csv_traj.t_s[-1], abs=1e-6)
    return report


def test_pipeline_runs_on_synthetic_default(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["run", str(PIPELINE), "--out", str(out), "--no-preview", "--task", "wrench", "--demo", "3"])
    assert code == 0
    report = _check_outputs(out)
    assert report["recognised_task"] == "wrench"
    assert report["observation"]["task"] == "wrench"
    text = capsys.readouterr().out
    assert "Recognised task: wrench" in text and "[check]" in text and "[timing]" in text
    assert not (out / "preview.html").exists()
    text = (out / "report.txt").read_text()
    assert "Recognised task: wrench" in text and "joint_limits" in text
    deg = report["scores"]["handover_orientation_error_deg"]
    assert f"Gripper orientation at the hand-over: {deg:.1f} deg from the recorded one" in text


def test_written_report_equals_the_returned_report(tmp_path):
    """``run``'s report.json is the report of the outcome ``app.run.run`` returns, its ``files``
    included (every file the run wrote, the report itself too); a failing plan without
    --allow-failing-checks lists no trajectory file."""
    from ipromp_pin.app.run import run

    out = tmp_path / "out"
    cfg = load_pipeline(PIPELINE, out_dir=out, task="wrench", demo=3, preview_html=False, ros1_bag=True)
    outcome = run(cfg, log=lambda _m: None, warn=lambda _m: None)
    report = outcome.report
    assert outcome.passed == report["passed"] and outcome.trajectory_written
    written = json.loads((out / "report.json").read_text())
    assert written == report
    assert report["files"] == {
        "trajectory_csv": str(out / "trajectory.csv"),
        "trajectory_json": str(out / "trajectory.json"),
        "retreat_csv": str(out / "retreat.csv"),  # the shipped tasks retreat after the hand-over
        "rosbag": str(out / "rosbag"),
        "ros1_bag": str(out / "run.bag"),
        "report": str(out / "report.json"),
        "report_text": str(out / "report.txt"),
    }
    assert sorted(p.name for p in out.iterdir()) == sorted(Path(f).name for f in report["files"].values())


def test_the_default_run_meets_the_human_in_time_with_every_check_passed(tmp_path):
    """The built-in default (issue 38): the robot at rest at the hand-over within 0.5 s of the human,
    every check passed, slowed for them by at most 1.3x, and only where they asked."""
    out = tmp_path / "out"
    assert main(["run", str(PIPELINE), "--out", str(out), "--no-preview", "--no-rosbag"]) == 0
    report = json.loads((out / "report.json").read_text())
    a = report["arrival"]
    assert report["passed"] and report["feasibility"]["checks"]["contact_speed"]["status"] == "pass"
    assert abs(a["delay_s"]) <= 0.5 and a["slowdown"] <= 1.3
    assert a["slowdown_delay_s"] <= a["robot_s"] - a["robot_start_s"]
    if a["slowdown"] > 1.0:
        assert a["slowdown_local"]


def test_pipeline_saved_model_gives_the_same_result(tmp_path):
    model = tmp_path / "model.npz"
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["run", str(PIPELINE), "--out", str(a), "--no-preview", "--save-model", str(model)]) == 0
    assert main(["run", str(PIPELINE), "--out", str(b), "--no-preview", "--model", str(model)]) == 0
    ra = json.loads((a / "report.json").read_text())
    rb = json.loads((b / "report.json").read_text())
    assert ra["posterior"] == rb["posterior"]
    assert (a / "trajectory.csv").read_text() == (b / "trajectory.csv").read_text()


@pytest.mark.realdata
def test_pipeline_runs_on_a_real_demo(tmp_path, chen2017_dir):
    out = tmp_path / "real"
    args = ["run", str(PIPELINE), "--dataset", str(chen2017_dir), "--task", "tape_hold", "--demo", "25"]
    assert main([*args, "--out", str(out), "--no-preview", "--ratio", "0.2"]) == 0
    report = _check_outputs(out)
    assert report["observation"]["task"] == "tape_hold"
    assert report["recognised_task"] in {"aluminum_hold", "spanner_handover", "tape_hold"}


def test_bad_pipeline_files_fail_clearly(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[observation]\nratio = 1.5\n")
    with pytest.raises(PipelineError, match="observation.ratio"):
        load_pipeline(bad)
    bad.write_text("[model]\nobserv = ['emg']\n")
    with pytest.raises(PipelineError, match="model.observ"):
        load_pipeline(bad)
    bad.write_text("[nonsense]\n")
    with pytest.raises(PipelineError, match="unknown section"):
        load_pipeline(bad)
    bad.write_text("this is = = not toml")
    with pytest.raises(PipelineError, match="not a valid TOML"):
        load_pipeline(bad)
    with pytest.raises(PipelineError, match="not found"):
        load_pipeline(tmp_path / "missing.toml")
    # the command line turns errors into one line and exit status 2
    assert main(["run", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "error:" in capsys.readouterr().err


def test_pipeline_named_instead_of_a_path_is_the_shipped_one(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert PIPELINES_DIR == PIPELINE.parent  # a source checkout ships its own pipelines/ folder
    assert resolve_pipeline_path("baxter_handover") == PIPELINE
    cfg = load_pipeline("baxter_handover")
    assert Path(cfg.source) == PIPELINE and cfg.robot == "baxter_left" and cfg.ratio == 0.2
    # a file of that name in the current folder wins over the shipped one
    (tmp_path / "baxter_handover").write_text("[observation]\nratio = 0.3\n")
    assert resolve_pipeline_path("baxter_handover") == Path("baxter_handover")
    assert load_pipeline("baxter_handover").ratio == 0.3
    with pytest.raises(PipelineError, match=r"no_such_pipeline: .* \(shipped pipelines: baxter_handover"):
        load_pipeline("no_such_pipeline")


def test_unknown_task_and_demo_index_fail_clearly(tmp_path, capsys):
    assert main(["run", str(PIPELINE), "--out", str(tmp_path), "--task", "juggling", "--no-preview"]) == 2
    assert "unknown task 'juggling'" in capsys.readouterr().err
    assert main(["run", str(PIPELINE), "--out", str(tmp_path), "--demo", "500", "--no-preview"]) == 2
    assert "out of range" in capsys.readouterr().err


def test_preview_command_writes_a_self_contained_page(tmp_path, capsys):
    page = tmp_path / "preview.html"
    assert main(["preview", str(PIPELINE), "--html", str(page), "--task", "tape"]) == 0
    html = page.read_text()
    assert 0 < page.stat().st_size < 10e6
    assert "tape" in html and "http://" not in html.replace("http://www.w3.org", "")
    assert "wrote" in capsys.readouterr().out


def test_live_preview_streams_the_observation_on_loopback(capsys):
    assert main(["preview", str(PIPELINE), "--no-wait", "--speed", "1000", "--port", "7391"]) == 0
    out = capsys.readouterr().out
    assert "live at http://127.0.0.1:" in out
    # the posterior is printed as samples stream in, then the final recognition
    assert out.count("  t=") >= 5 and "[preview] recognised" in out


def test_preview_content_shows_one_clock_and_skipped_checks():
    """The page's observed fraction is of the human's motion, every time on it (the robot's
    trajectory, the checks' times) is on the human's clock and points at a sample of the trajectory,
    and a check that could not be made is marked skipped."""
    import re

    from ipromp_pin.app.session import prepare_session
    from ipromp_pin.outputs.preview_content import preview_content
    from ipromp_pin.planning.one_shot import plan

    cfg = load_pipeline(PIPELINE, task="tape", demo=2)
    prep = prepare_session(cfg, log=lambda _msg: None)
    result = plan(prep.model, prep.robot, prep.observed(), prep.suite, prep.context)
    content = preview_content(result, prep.robot, prep.demo)
    assert content.human_duration_s == prep.demo.duration_s and content.human_duration_source == "recorded"
    assert content.observed_fraction() == pytest.approx(prep.observation.t[-1] / prep.demo.duration_s)
    assert content.observed_fraction() == pytest.approx(cfg.ratio, abs=0.02)
    assert content.t_s[0] == pytest.approx(result.start_s) and content.t_s[0] > 0.1  # the human's clock
    assert "human's motion" in content.timebase
    limits = result.checks["joint_limits"]
    shown = [c for c in content.feasibility if c.name == "joint_limits"][0].detail
    t_shown = float(re.search(r"t=(\d+\.\d+) s", shown).group(1))
    assert t_shown == pytest.approx(result.trajectory.t_s[limits.measures.sample], abs=0.006)
    for check in content.feasibility:
        for t in re.findall(r"t=(\d+\.\d+) s", check.detail):
            assert content.t_s[0] - 0.005 <= float(t) <= content.duration_s + 0.005
    # a check that could not be made is shown as skipped
    blind = without_uncertainty(result, prep.suite)
    skipped = [c for c in preview_content(blind, prep.robot, None).feasibility if c.status == "skip"]
    assert [c.name for c in skipped] == ["uncertainty"] and skipped[0].passed and not skipped[0].required
    unknown = preview_content(blind, prep.robot, None)
    assert unknown.human_duration_source == "predicted"
    assert unknown.human_duration_s == pytest.approx(result.prediction.duration_s)


def test_phase_plot_gets_the_joint_posterior_of_task_and_phase(tmp_path, monkeypatch):
    from scipy.special import logsumexp

    from ipromp_pin.outputs import plots

    seen = {}
    original = plots.plot_phase_posterior

    def spy(alphas, log_posterior, path, **kwargs):
        seen.update(log_posterior=log_posterior, ylabel=kwargs.get("ylabel"))
        return original(alphas, log_posterior, path, **kwargs)

    monkeypatch.setattr(plots, "plot_phase_posterior", spy)
    out = tmp_path / "plots"
    assert main(["run", str(PIPELINE), "--out", str(out), "--no-preview", "--plots", "--task", "wrench"]) == 0
    report = json.loads((out / "report.json").read_text())
    joint = seen["log_posterior"]
    assert seen["ylabel"] == "log p(task, alpha | observation)"
    # one distribution over every (task, phase candidate): its task marginals are the task posterior
    assert logsumexp(np.concatenate(list(joint.values()))) == pytest.approx(0.0, abs=1e-9)
    for task, values in joint.items():
        assert np.exp(logsumexp(values)) == pytest.approx(report["posterior"][task], abs=1e-9)
    for name in ("prediction.png", "phase_posterior.png", "distributions.png", "torques.png"):
        assert (out / name).stat().st_size > 5000


def test_console_script_exits_fast_with_the_commands_status_and_output(tmp_path):
    """``ipromp-pin`` (cli.console_main) skips the interpreter's teardown but keeps the exit status,
    the flushed output and the written files."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    command = [sys.executable, "-c", "from ipromp_pin.app import console_main; console_main()"]
    ok = subprocess.run(
        [*command, "synth", str(tmp_path / "d"), "--tasks", "2", "--demos", "2"],
        env=env, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert ok.returncode == 0 and "wrote 4 demos" in ok.stdout
    assert len(list((tmp_path / "d").rglob("*.npz"))) == 4
    bad = subprocess.run(
        [*command, "run", str(tmp_path / "missing.toml")], env=env, capture_output=True, text=True
    )
    assert bad.returncode == 2 and "missing.toml" in bad.stderr and "Traceback" not in bad.stderr


def _tiny_workspace_robot(tmp_path: Path) -> Path:
    """Baxter's settings with a workspace the hand-over cannot be in: every plan fails its checks."""
    text = ROBOT_FILE.read_text().replace("max_m = [1.16, 0.45, 0.57]", "max_m = [0.56, -0.44, -0.07]")
    path = tmp_path / "tiny_workspace.toml"
    path.write_text(text)
    return path


def test_failing_checks_exit_3_without_trajectory_files(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    assert run_tiny(tiny, out) == 0
    assert (out / "trajectory.csv").exists()
    robot = _tiny_workspace_robot(tmp_path)
    assert run_tiny(tiny, out, "--robot", str(robot)) == cli.EXIT_CHECKS_FAILED
    line = one_error_line(capsys.readouterr().err)
    assert "failed its checks (workspace" in line and "not written" in line
    # the earlier run's trajectory is gone too: a script cannot pick up a stale plan
    assert sorted(p.name for p in out.iterdir()) == ["report.json", "report.txt"]
    report = json.loads((out / "report.json").read_text())
    assert report["passed"] is False and "workspace" in report["feasibility"]["failures"]
    # slowing down cannot move the hand-over into the workspace: the plan is not slowed for the rest
    assert report["feasibility"]["checks"]["workspace"].get("slowdown") is None


def test_allowed_failing_checks_write_marked_files(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    robot = _tiny_workspace_robot(tmp_path)
    assert run_tiny(tiny, out, "--robot", str(robot), "--allow-failing-checks") == cli.EXIT_CHECKS_FAILED
    assert "written marked as failing" in one_error_line(capsys.readouterr().err)
    text = (out / "trajectory.csv").read_text()
    assert text.startswith("# ipromp_pin: checks FAILED (workspace")
    doc = json.loads((out / "trajectory.json").read_text())
    assert doc["ipromp_pin_checks"]["passed"] is False and "workspace" in doc["ipromp_pin_checks"]["failures"]
    a, b = read_trajectory_csv(out / "trajectory.csv"), read_trajectory_json(out / "trajectory.json")
    assert np.array_equal(a.q, b.q) and a.q.shape[1] == 7


def test_failed_save_over_an_existing_model_keeps_it(tmp_path, tiny, monkeypatch, capsys):
    ds, model = tiny
    target = tmp_path / "m.npz"
    target.write_bytes(model.read_bytes())

    def fail_midway(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", fail_midway)
    assert main(["train", str(ds), "--out", str(target)]) == 2
    assert "No space left on device" in one_error_line(capsys.readouterr().err)
    assert target.read_bytes() == model.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]
    monkeypatch.undo()
    IProMP.load(target)


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Relative path -> content of every file below ``folder`` (bag folders included)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize(
    "module, stage",
    [(plan_files, "report_text"), (staging, "trajectory_json_text"), (preview_module, "render_html")],
)
def test_run_failing_midway_leaves_the_earlier_outputs(tmp_path, tiny, monkeypatch, capsys, module, stage):
    out = tmp_path / "out"
    ds, model = tiny
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out)]
    assert main(args) == 0
    before = _snapshot(out)
    assert "preview.html" in before and "rosbag/metadata.yaml" in before

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(module, stage, boom)
    assert main([*args, "--task", "wrench", "--demo", "0"]) == 2
    assert "No space left" in one_error_line(capsys.readouterr().err)
    assert _snapshot(out) == before


def test_run_without_preview_removes_the_stale_preview(tmp_path, tiny):
    out = tmp_path / "out"
    ds, model = tiny
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out)]
    assert main(args) == 0 and (out / "preview.html").exists()
    (out / "notes.txt").write_text("mine")
    assert main([*args, "--no-preview", "--task", "wrench"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "notes.txt", "report.json", "report.txt", "retreat.csv", "rosbag", "trajectory.csv",
        "trajectory.json",
    ]  # fmt: skip
