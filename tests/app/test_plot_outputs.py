"""``run --plots`` and ``replay --plots``: the figures they write, whose numbers agree with the report
(the separation's smallest clearance and largest contact-speed ratio, the object held while the task
says so), and the rosbag2 folder ``replay`` writes as ``run`` does."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import PIPELINE, run_tiny
from helpers_human import write_leaning_dataset

from ipromp_pin.app import main
from ipromp_pin.outputs import plots, plots_motion
from ipromp_pin.outputs.rosbag import TOPIC_JOINT_STATES, TOPIC_TRAJECTORY
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.objects import load_objects


def spied(monkeypatch, module, name: str) -> list[dict]:
    """The arguments of every call of ``module.name`` (still drawn)."""
    calls: list[dict] = []
    original = getattr(module, name)

    def spy(*args, **kwargs):
        calls.append({"args": args, **kwargs})
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, spy)
    return calls


def read_rosbag2(folder: Path) -> dict[str, list]:
    """Topic -> (record stamp [ns], message) of a rosbag2 folder, read with ``rosbags``."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    out: dict[str, list] = {}
    with Reader(folder) as reader:
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, store.deserialize_cdr(raw, conn.msgtype)))
    return out


def test_run_plots_draw_the_motion_the_separation_and_the_held_object_as_the_report_says(
    tiny, tmp_path, monkeypatch
):
    separation = spied(monkeypatch, plots_motion, "plot_separation")
    motion = spied(monkeypatch, plots_motion, "plot_joint_motion")
    torques = spied(monkeypatch, plots, "plot_torques")
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--plots") == 0
    report = json.loads((out / "report.json").read_text())
    for name in ("motion.png", "separation.png", "torques.png", "prediction.png"):
        assert (out / name).stat().st_size > 5000
    assert {"plot_motion", "plot_separation", "plot_torques"} <= set(report["files"])
    checks = report["feasibility"]["checks"]
    (call,) = separation
    t, body, _, ratio = call["args"][:4]
    judged = call["judged"]
    assert body[judged].min() == pytest.approx(checks["human_clearance"]["min_separation_m"], abs=1e-9)
    assert t[judged][np.argmin(body[judged])] == pytest.approx(checks["human_clearance"]["t_s"])
    assert ratio[judged].max() == pytest.approx(checks["contact_speed"]["max_speed_ratio"], rel=1e-9)
    assert ratio.max() > 0.1  # an approach within S_p: the ratio compared is not the empty 0
    assert call["planning_limit_ratio"] == pytest.approx(checks["contact_speed"]["planning_limit_ratio"])
    # the motion on the report's clock: from the robot's start to the end of the retreat
    traj = read_trajectory_csv(out / "trajectory.csv")
    retreat = read_trajectory_csv(out / "retreat.csv")
    (drawn,) = motion
    t_m = drawn["args"][0]
    assert t_m[0] == pytest.approx(traj.t_s[0]) and t_m[-1] == pytest.approx(retreat.t_s[-1])
    np.testing.assert_allclose(drawn["args"][1][0][: traj.n_samples], traj.q, atol=1e-6)
    # the object held where its task says: a robot_gives object until the hand-over, a received one
    # from it on, over approach and retreat alike
    (tq,) = torques
    t_q, held = tq["args"][0], tq["held"]
    handover = traj.t_s[-1]
    obj = load_objects(None).for_task(report["recognised_task"])
    expected = t_q <= handover + 1e-9 if obj.holder == "robot_gives" else t_q >= handover - 1e-9
    np.testing.assert_array_equal(held, expected)
    assert 0.2 < held.mean() < 0.8  # a span, not a sliver


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """A replay with --plots of a demo with a tracked skeleton (the human checks judge it), and the
    arguments its separation figure was drawn with."""
    folder = tmp_path_factory.mktemp("skeleton_dataset")
    tasks = write_leaning_dataset(folder, load_robot("baxter_left").settings.human)
    out = tmp_path_factory.mktemp("replay")
    args = ["replay", str(PIPELINE), "--dataset", str(folder), "--task", tasks[0], "--demo", "1"]
    with pytest.MonkeyPatch.context() as mp:
        calls = spied(mp, plots_motion, "plot_separation")
        code = main([*args, "--out", str(out), "--allow-failing-checks", "--plots", "--no-preview"])
    assert code in (0, 3)
    return out, json.loads((out / "report.json").read_text()), calls


def test_replay_plots_agree_with_its_report(replayed):
    out, report, calls = replayed
    assert (out / "motion.png").stat().st_size > 5000 and (out / "separation.png").stat().st_size > 5000
    assert {"plot_motion", "plot_separation", "rosbag"} <= set(report["files"])
    (call,) = calls
    body, ratio, judged = call["args"][1], call["args"][3], call["judged"]
    checks = report["checks"]  # the replay report rounds to 6 decimals
    assert body[judged].min() == pytest.approx(checks["human_clearance"]["min_separation_m"], abs=1e-6)
    assert ratio[judged].max() == pytest.approx(checks["contact_speed"]["max_speed_ratio"], abs=1e-6)
    assert body[judged].min() == pytest.approx(report["human_min_separation_m"], abs=1e-6)
    committed = [e for e in json.loads((out / "replans.json").read_text())["replans"] if e["committed"]]
    np.testing.assert_allclose(call["ticks_s"], [e["t_s"] for e in committed])


def test_replay_writes_the_commanded_trajectory_into_a_rosbag(replayed):
    out, report, _ = replayed
    traj = read_trajectory_csv(out / "trajectory.csv")
    bag = read_rosbag2(out / "rosbag")
    failed = not report["passed"]
    prefix = "/ipromp_pin/failed_checks/" if failed else "/ipromp_pin/"
    topic = TOPIC_TRAJECTORY.replace("/ipromp_pin/", prefix)
    ((stamp, msg),) = bag[topic]
    assert len(msg.points) == traj.n_samples
    np.testing.assert_allclose([p.positions for p in msg.points], traj.q, atol=1e-6)
    states = bag[TOPIC_JOINT_STATES.replace("/ipromp_pin/", prefix)]
    assert len(states) == traj.n_samples
    stamps = np.array([s for s, _ in states]) * 1e-9
    np.testing.assert_allclose(stamps - stamps[0], traj.t_s - traj.t_s[0], atol=1e-6)  # one per sample
    assert any(t.startswith("/ipromp_pin/human/") for t in bag)


def test_replay_no_rosbag_writes_none(tiny, tmp_path):
    ds, model = tiny
    out = tmp_path / "out"
    common = ["--dataset", str(ds), "--model", str(model), "--out", str(out), "--no-preview"]
    assert main(["replay", str(PIPELINE), *common, "--no-rosbag"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert "rosbag" not in report["files"] and not (out / "rosbag").exists()
    assert "plot_motion" not in report["files"]
