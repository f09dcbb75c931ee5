"""``ipromp-pin replay`` and ``evaluate --closed-loop``: the files they write, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.app import main
from ipromp_pin.motion.limits import read_limit_profile
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv, read_trajectory_json
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.native import write_demo
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.safety.speed_limits import limit_ratios

PIPELINE = Path(__file__).resolve().parents[2] / "pipelines" / "baxter_handover.toml"


def test_replay_of_the_synthetic_default_writes_every_file(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["replay", str(PIPELINE), "--out", str(out), "--task", "tape", "--demo", "2", "--start-ratio", "0.25"]
    )
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    replans = json.loads((out / "replans.json").read_text())
    traj = read_trajectory_csv(out / "trajectory.csv")
    np.testing.assert_allclose(read_trajectory_json(out / "trajectory.json").q, traj.q, atol=1e-9)
    robot = load_robot("baxter_left")
    profile = read_limit_profile(out / "limits.toml", robot)
    assert report["limit_profile"]["name"] == profile.name == "demonstrated"
    # every control sample within the profile written beside it, at rest at both ends
    dt = traj.t_s[1] - traj.t_s[0]
    assert dt == pytest.approx(0.01)
    motion = Trajectory(traj.t_s, traj.q, traj.qd, traj.qdd, traj.joint_names)
    assert np.all(limit_ratios(motion, profile.limits)[0] <= 1 + 1e-5)
    assert not np.abs(traj.qd[0]).any() and not np.abs(traj.qd[-1]).any()
    assert report["demo"]["task"] == "tape" and report["settings"]["start_ratio"] == 0.25
    assert report["settings"]["condition_noise"] == 0.3 and report["model"]["noise_ratio"] > 0
    assert report["collisions"] == 0 and report["max_limit_ratio"] <= 1 + 1e-6
    assert report["replans"] == len(replans["replans"]) > 10
    first = replans["replans"][0]
    assert first["observed_ratio"] == pytest.approx(0.25, abs=0.02) and first["committed"]
    for key in ("t_s", "posterior", "predicted_handover_s", "predicted_handover_position_m", "reason"):
        assert key in first
    assert report["handover_error_cm"] == pytest.approx(report["handover_error_cm"]) and report["final_task"]
    text = (out / "report.txt").read_text()
    assert "Limit profile: demonstrated" in text and "Arrival" in text
    page = (out / "preview.html").read_text()
    assert 'id="ipromp-timeline-data"' in page and "iprompTimeline" in page
    data = json.loads(page.split('id="ipromp-timeline-data">')[1].split("</script>")[0].replace("<\\/", "</"))
    assert len(data["events"]) == report["replans"]
    assert "Hand-over error" in capsys.readouterr().out


def _write_dataset(folder: Path, short: bool = False) -> Path:
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    for task, demos in ds.demos.items():
        for i, d in enumerate(demos):
            if short and task == ds.tasks[0] and i == len(demos) - 1:
                d = d.slice(4)
            write_demo(d, folder / task / f"{d.name}.npz")
    return folder


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--start-ratio", "1.0"], "command line: field 'start_ratio': must be in (0, 1), got 1.0"),
        (["--start-ratio", "0"], "field 'start_ratio': must be in (0, 1)"),
        (["--replan-rate", "0"], "field 'replan_rate_hz': must be a positive rate, got 0.0"),
        (["--replan-rate", "200"], "field 'replan_rate_hz': 200 Hz is faster than the control rate 100 Hz"),
        (["--limits", "fast"], "field 'limits': unknown limit profile 'fast'"),
        (["--condition-noise", "-1"], "field 'condition_noise': must be a positive number"),
        (["--condition-noise", "x"], "field 'condition_noise': must be a positive number"),
        (
            ["--observe", "orientation,/left_hand_1"],
            "option '--observe': channel group '/left_hand_1' not in the data",
        ),
    ],
)
def test_replay_bad_input_fails_in_one_line_before_computing(tmp_path, capsys, args, message):
    code = main(["replay", str(PIPELINE), "--out", str(tmp_path / "o"), *args])
    captured = capsys.readouterr()
    assert code == 2
    err = captured.err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
    assert "[model]" not in captured.out  # nothing was trained
    assert not (tmp_path / "o").exists()


def test_replay_bad_limit_profile_and_short_demo(tmp_path, capsys):
    bad = tmp_path / "limits.toml"
    bad.write_text("velocity_rad_s = 1.0\nacceleration_rad_s2 = [1, 1, 1, -2, 1, 1, 1]\njerk_rad_s3 = 10\n")
    code = main(["replay", str(PIPELINE), "--out", str(tmp_path / "o"), "--limits", str(bad)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and f"{bad}: field 'acceleration_rad_s2': value -2.0 is not positive" in err
    data = _write_dataset(tmp_path / "data", short=True)
    short = ["replay", str(PIPELINE), "--out", str(tmp_path / "o"), "--dataset", str(data)]
    short += ["--task", "rod", "--demo", "-1"]
    code = main([*short, "--start-ratio", "0.2"])  # offline: refused before training
    captured = capsys.readouterr()
    assert code == 2 and "field 'start_ratio': the start window" in captured.err
    assert "holds fewer than 2 samples" in captured.err and ".npz" in captured.err
    assert "[model]" not in captured.out
    code = main(short)  # the online rule: its time needs the model's nominal duration
    err = capsys.readouterr().err.strip()
    assert (
        code == 2
        and len(err.splitlines()) == 1
        and ".npz: field 'start_after_s': the robot would start" in err
    )
    assert "after the demo's end" in err and not (tmp_path / "o").exists()


def test_evaluate_closed_loop_adds_the_closed_loop_fields(tmp_path, capsys):
    data = _write_dataset(tmp_path / "data")
    out = tmp_path / "eval.json"
    args = ["evaluate", str(data), "--protocol", "splits", "--closed-loop", "--observe", "orientation,emg"]
    args += ["--grid", "full", "--n-train", "4", "--ratios", "0.2", "--splits", "1", "--n-test", "2"]
    args += ["--json", str(out), "--jobs", "1", "--robot", "baxter_left"]
    assert main(args) == 0
    doc = json.loads(out.read_text())
    assert doc["meta"]["closed_loop"]["limits"] == "demonstrated"
    cells = doc["cells"]
    # the paper's start after 20 % of each test demo, then the online rule: after 20 % of the model's
    # nominal duration (the training demos' mean length), whatever the test demo's length
    assert [c["window"]["kind"] for c in cells] == ["ratio"] * 2 + ["train_fraction"] * 2
    for c in cells[2:]:
        # never before the rule's time; later only while the observation matches none of the tasks
        # (require_known: 4 training demos per task make a narrow model)
        starts = sorted({t["closed_loop_start_s"] for t in c["closed_loop_trials"]})
        assert c["window"]["seconds"] - 0.05 < starts[0] <= c["window"]["seconds"]
    for c in cells:
        for key in (
            "closed_loop_handover_error_cm",
            "closed_loop_final_error_cm",
            "one_shot_handover_error_cm",
            "arrival_delay_s",
            "max_limit_ratio",
            "refused_replans",
            "collisions",
        ):
            assert c[key] is not None, key
        assert c["max_limit_ratio"] <= 1 + 1e-6 and c["collisions"] == 0
        assert c["n_test"] == len(c["closed_loop_trials"]) == 2
        # replays that never started (no re-plan: the task unknown throughout) are counted
        assert c["never_started"] == sum(t["closed_loop_replans"] == 0 for t in c["closed_loop_trials"])
        trial_errors = [t["closed_loop_handover_error_cm"] for t in c["closed_loop_trials"]]
        assert c["closed_loop_handover_error_cm"] == pytest.approx(float(np.median(trial_errors)), abs=1e-3)
    md = out.with_suffix(".md").read_text()
    assert "### Closed loop, protocol `splits`" in md and "one-shot" in md and "replays never started" in md
    capsys.readouterr()
    for extra, field in ((["--freeze-phase", "2"], "freeze_phase"), (["--ratios", "1.0"], "start_ratio")):
        assert main([*args, *extra]) == 2
        captured = capsys.readouterr()
        assert f"command line: field '{field}'" in captured.err and "read " not in captured.out


def test_closed_loop_evaluation_chooses_the_model_settings_for_the_hand_over(tmp_path, monkeypatch):
    """The closed loop's models are fitted with the robot's kinematics (coupling and conditioning
    chosen for the hand-over position, as run, replay and evaluate choose them) and the gripper's
    rotations (the hand-over orientation estimate)."""
    seen = []
    fit = IProMP.fit

    def spy(self, data, y=None, *, fk=None, fk_rot=None):
        seen.append((fk, fk_rot))
        return fit(self, data, y, fk=fk, fk_rot=fk_rot)

    monkeypatch.setattr(IProMP, "fit", spy)
    data = _write_dataset(tmp_path / "data")
    args = ["evaluate", str(data), "--protocol", "splits", "--closed-loop", "--observe", "orientation,emg"]
    args += ["--grid", "full", "--n-train", "4", "--ratios", "0.2", "--splits", "1", "--n-test", "2"]
    args += ["--json", str(tmp_path / "eval.json"), "--jobs", "1"]
    assert main(args) == 0
    assert seen and all(fk is not None and fk_rot is not None for fk, fk_rot in seen)
    assert seen[0][0](np.zeros((2, 7))).shape == (2, 3) and seen[0][1](np.zeros((2, 7))).shape == (2, 3, 3)


def test_a_replay_into_a_run_folder_leaves_the_replay_files_only(tmp_path, tiny):
    """An output folder holds one command's consistent set: the run's retreat and bag, which the
    replay does not write, go (the replay's trajectory does not end where that retreat starts)."""
    out = tmp_path / "out"
    ds, model = tiny
    common = ["--dataset", str(ds), "--model", str(model), "--out", str(out), "--no-preview"]
    assert main(["run", str(PIPELINE), *common]) == 0
    assert (out / "retreat.csv").exists() and (out / "rosbag").is_dir()
    (out / "notes.txt").write_text("mine")
    assert main(["replay", str(PIPELINE), *common]) == 0
    report = json.loads((out / "report.json").read_text())
    written = {Path(p).name for p in report["files"].values()}
    assert sorted(p.name for p in out.iterdir()) == sorted(written | {"notes.txt"})
    assert "retreat.csv" not in written and "run.bag" not in written
    # the bag is the replay's own: the commanded trajectory, no retreat
    from rosbags.rosbag2 import Reader

    with Reader(out / "rosbag") as reader:
        topics = {c.topic for c in reader.connections}
    assert "/ipromp_pin/planned_trajectory" in topics and "/ipromp_pin/retreat_trajectory" not in topics


def test_a_replay_turned_unknown_reports_and_previews_the_stop_hold_and_retreat(tmp_path, capsys):
    """The held-out demo's observed channels buried in noise from 40 % of it on (a motion the model
    never learned): the robot, started on a known task, stops, holds and retreats; the report says
    when on its clock (0: the human's motion's start), its schema holds, the preview marks the times."""
    import jsonschema

    from ipromp_pin.schemas import load_schema

    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    rng = np.random.default_rng(1)
    for task, demos in ds.demos.items():
        for i, d in enumerate(demos):
            if task == "rod" and i == len(demos) - 1:
                cut = int(0.4 * d.n_samples)
                o, e = d.groups["orientation"][cut:], d.groups["emg"][cut:]
                o += rng.standard_normal(o.shape)  # still unit quaternions, another way round
                o /= np.linalg.norm(o, axis=1, keepdims=True)
                e += np.abs(3.0 * rng.standard_normal(e.shape))
            write_demo(d, tmp_path / "data" / task / f"{d.name}.npz")
    out = tmp_path / "out"
    args = ["replay", str(PIPELINE), "--out", str(out), "--dataset", str(tmp_path / "data")]
    args += ["--task", "rod", "--demo", "-1", "--start-ratio", "0.2", "--unknown-hold", "0.3"]
    assert main(args) == 0
    report = json.loads((out / "report.json").read_text())
    jsonschema.Draft202012Validator(load_schema("replay_report")).validate(report)
    replans = json.loads((out / "replans.json").read_text())
    jsonschema.Draft202012Validator(load_schema("replans")).validate(replans)
    u = report["unknown_task"]
    assert u["require_known"] and u["hold_s"] == 0.3 == report["settings"]["unknown_hold_s"]
    kinds = [e["kind"] for e in u["events"]]  # a flicker of known may resume it in between
    assert kinds[0] == "unknown" and kinds[-2:] == ["hold", "retreat"]
    times = {k: [e["t_s"] for e in u["events"] if e["kind"] == k] for k in set(kinds)}
    assert (u["stop_s"], u["hold_start_s"], u["retreat_s"]) == (
        times["unknown"][0],
        times["hold"][0],
        times["retreat"][0],
    )
    assert report["start_s"] < u["stop_s"] < u["hold_start_s"] < u["retreat_s"]
    assert [e["t_s"] for e in u["events"]] == sorted(e["t_s"] for e in u["events"])
    assert u["retreat_s"] >= times["hold"][-1] + 0.3 - 1e-6
    # the report's clock is the trajectory's and the re-plans' (0: the human's motion's start)
    stop = next(r for r in replans["replans"] if r["action"] == "stop")
    assert stop["t_s"] == u["stop_s"] and not stop["known"] and stop["committed"]
    traj = read_trajectory_csv(out / "trajectory.csv")
    i_hold = int(round(u["hold_start_s"] / 0.01))
    assert traj.t_s[i_hold] == pytest.approx(u["hold_start_s"]) and not traj.qd[i_hold].any()
    assert traj.qd[i_hold - 1].any()  # still moving just before the hold
    np.testing.assert_allclose(traj.q[-1], ds.demos["rod"][-1].groups["robot"][0], atol=1e-6)  # at rest
    text = (out / "report.txt").read_text()
    assert f"Unknown task: held at rest at {u['hold_start_s']:.2f} s" in text
    assert f"Unknown task: retreated at {u['retreat_s']:.2f} s" in text
    page = (out / "preview.html").read_text()
    data = json.loads(page.split('id="ipromp-timeline-data">')[1].split("</script>")[0].replace("<\\/", "</"))
    assert any(
        line.startswith(f"Unknown task: turned unknown, stopping at {u['stop_s']:.2f} s")
        for line in data["summary"]
    )
    marked = {e["t_s"]: e["action"] for e in data["events"] if e["action"]}
    assert marked[u["stop_s"]].startswith("stop") and marked[u["retreat_s"]].startswith("retreat")
    assert "Unknown task: retreated at" in capsys.readouterr().out
    # a hold outside its plausible range: one line naming the field, nothing computed
    assert main([*args[:-1], "20"]) == 2
    err = capsys.readouterr().err.strip()
    assert "command line: field 'unknown_hold_s': implausible value 20 s" in err and "\n" not in err
