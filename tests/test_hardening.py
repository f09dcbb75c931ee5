"""Nothing silently wrong, no tracebacks, no lost files: one test per class of issue 16.

Classes: (2) channels and joints matched by name, (3) failing checks exit non-zero without
trajectory files, (4) no lost files, (5) one-line errors instead of tracebacks, (6) a rejected
stream sample leaves no trace, (7) the live preview's disconnects and Host check, (8) progress on a
terminal only, errors on their own line. Class 1 is in test_plausibility.py and test_model_checks.py,
the atomic writer in test_atomic.py.
"""

from __future__ import annotations

import dataclasses
import http.client
import json
import logging
import os
import re
import socket
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin import cli
from ipromp_pin.cli import main
from ipromp_pin.commands import run as run_command
from ipromp_pin.commands.config import load_pipeline
from ipromp_pin.exceptions import DataError, InfeasibleError, ModelError, ObservationError
from ipromp_pin.handover.one_shot import check_model_joints
from ipromp_pin.motion.timing import MAX_TRAJECTORY_SAMPLES, JointLimits, time_path
from ipromp_pin.outputs import staging
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv, read_trajectory_json
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset, read_demo, write_demo
from ipromp_pin.robot import load_robot

ROOT = Path(__file__).resolve().parents[1]
PIPELINE = ROOT / "pipelines" / "baxter_handover.toml"
ROBOT_FILE = ROOT / "robots" / "baxter_left.toml"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> tuple[Path, Path]:
    """A native dataset of 2 tasks x 4 synthetic demos and a model trained on it."""
    root = tmp_path_factory.mktemp("tiny")
    assert main(["synth", str(root / "ds"), "--tasks", "2", "--demos", "4"]) == 0
    assert main(["train", str(root / "ds"), "--out", str(root / "m.npz")]) == 0
    return root / "ds", root / "m.npz"


def _run(tiny, out: Path, *extra: str) -> int:
    ds, model = tiny
    return main(["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out),
                 "--no-preview", *extra])  # fmt: skip


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err
    errors = [ln for ln in lines if ": error: " in ln]
    assert len(errors) == 1, err
    return errors[0]


def _tiny_workspace_robot(tmp_path: Path) -> Path:
    """Baxter's settings with a workspace the hand-over cannot be in: every plan fails its checks."""
    text = ROBOT_FILE.read_text().replace("max_m = [1.16, 0.45, 0.57]", "max_m = [0.56, -0.44, -0.07]")
    path = tmp_path / "tiny_workspace.toml"
    path.write_text(text)
    return path


# ------------------------------------------------------------------ (2) matching by name
def test_observation_channels_are_matched_by_name():
    ds = random_dataset(3, n_demos=5)
    model = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    obs = ds.demos["task1"][0].head(0.3, ["a", "b"])
    perm = [2, 0, 1]
    shuffled = dataclasses.replace(
        obs,
        groups={**obs.groups, "b": obs.groups["b"][:, perm]},
        channel_names={**obs.channel_names, "b": tuple(obs.channel_names["b"][i] for i in perm)},
    )
    a, b = model.predict(obs), model.predict(shuffled)
    assert np.array_equal(a.q_mean, b.q_mean) and np.array_equal(a.log_posterior, b.log_posterior)
    renamed = dataclasses.replace(obs, channel_names={**obs.channel_names, "b": ("x", "y", "z")})
    with pytest.raises(ObservationError, match="not the expected"):
        model.predict(renamed)


def test_training_channels_are_matched_by_name():
    ds = random_dataset(4, n_tasks=2, n_demos=4)
    reference = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    demo = ds.demos["task1"][2]
    perm = [1, 0]
    ds.demos["task1"][2] = dataclasses.replace(
        demo,
        groups={**demo.groups, "a": demo.groups["a"][:, perm]},
        channel_names={**demo.channel_names, "a": tuple(demo.channel_names["a"][i] for i in perm)},
    )
    model = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    assert np.array_equal(model.scaler_.scale, reference.scaler_.scale)
    assert np.array_equal(model.models_["task1"].mean, reference.models_["task1"].mean)


def test_native_csv_columns_in_another_order_read_the_same(tmp_path, tiny):
    ds, _ = tiny
    demo = read_demo(ds / "rod" / "rod_000.npz")
    write_demo(demo, tmp_path / "a.csv")
    lines = (tmp_path / "a.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines]
    order = [0, *range(len(rows[0]) - 1, 0, -1)]  # t first, every other column reversed
    (tmp_path / "b.csv").write_text("\n".join(",".join(r[i] for i in order) for r in rows) + "\n")
    a, b = read_demo(tmp_path / "a.csv"), read_demo(tmp_path / "b.csv")
    assert np.array_equal(a.groups["robot"], b.groups["robot"])
    assert a.channel_names["robot"] == b.channel_names["robot"]  # the robot's order, by name
    model = IProMP.load(tiny[1])
    pa = model.predict(a.head(0.2, model.observe_))
    pb = model.predict(b.head(0.2, model.observe_))  # emg channels reversed: matched by name
    assert np.array_equal(pa.q_mean, pb.q_mean)


def test_model_joints_must_be_the_robots(tmp_path, tiny, capsys):
    model = IProMP.load(tiny[1])
    check_model_joints(model, load_robot("baxter_left"))
    with pytest.raises(ModelError, match=r"predicts joints \['left_s0'.*moves \['right_s0'"):
        check_model_joints(model, load_robot("baxter_right"))
    out = tmp_path / "out"
    # recordings are read by the robot's joint names: the left-arm demos have no right_s0
    assert _run(tiny, out, "--robot", "baxter_right") == 2
    assert "field 'right_s0': unknown joint name" in _one_error_line(capsys.readouterr().err)
    # the synthetic demos are left-arm demos too, but with --model the model's joints are checked
    argv = ["run", str(PIPELINE), "--model", str(tiny[1]), "--robot", "baxter_right", "--out", str(out)]
    assert main(argv) == 2
    assert "robot 'baxter_right' moves ['right_s0'" in _one_error_line(capsys.readouterr().err)
    assert not out.exists()


# -------------------------------------------------- (3) failing checks: exit 3, no trajectory
def test_failing_checks_exit_3_without_trajectory_files(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    assert _run(tiny, out) == 0
    assert (out / "trajectory.csv").exists()
    robot = _tiny_workspace_robot(tmp_path)
    assert _run(tiny, out, "--robot", str(robot)) == cli.EXIT_CHECKS_FAILED
    line = _one_error_line(capsys.readouterr().err)
    assert "failed its checks (workspace)" in line and "not written" in line
    # the earlier run's trajectory is gone too: a script cannot pick up a stale plan
    assert sorted(p.name for p in out.iterdir()) == ["report.json", "report.txt"]
    report = json.loads((out / "report.json").read_text())
    assert report["passed"] is False and report["feasibility"]["failures"] == ["workspace"]


def test_allowed_failing_checks_write_marked_files(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    robot = _tiny_workspace_robot(tmp_path)
    assert _run(tiny, out, "--robot", str(robot), "--allow-failing-checks") == cli.EXIT_CHECKS_FAILED
    assert "written marked as failing" in _one_error_line(capsys.readouterr().err)
    text = (out / "trajectory.csv").read_text()
    assert text.startswith("# ipromp_pin: checks FAILED (workspace)")
    doc = json.loads((out / "trajectory.json").read_text())
    assert doc["ipromp_pin_checks"] == {"passed": False, "failures": ["workspace"]}
    a, b = read_trajectory_csv(out / "trajectory.csv"), read_trajectory_json(out / "trajectory.json")
    assert np.array_equal(a.q, b.q) and a.q.shape[1] == 7


# ----------------------------------------------------------------------- (4) no lost files
def test_failed_save_over_an_existing_model_keeps_it(tmp_path, tiny, monkeypatch, capsys):
    ds, model = tiny
    target = tmp_path / "m.npz"
    target.write_bytes(model.read_bytes())

    def fail_midway(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", fail_midway)
    assert main(["train", str(ds), "--out", str(target)]) == 2
    assert "No space left on device" in _one_error_line(capsys.readouterr().err)
    assert target.read_bytes() == model.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]
    monkeypatch.undo()
    IProMP.load(target)


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Relative path -> content of every file below ``folder`` (bag folders included)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize(
    "module, stage",
    [(run_command, "report_text"), (staging, "trajectory_json_text"), (run_command, "render_html")],
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
    assert "No space left" in _one_error_line(capsys.readouterr().err)
    assert _snapshot(out) == before


def test_run_without_preview_removes_the_stale_preview(tmp_path, tiny):
    out = tmp_path / "out"
    ds, model = tiny
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out)]
    assert main(args) == 0 and (out / "preview.html").exists()
    (out / "notes.txt").write_text("mine")
    assert main([*args, "--no-preview", "--task", "wrench"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "notes.txt", "report.json", "report.txt", "rosbag", "trajectory.csv", "trajectory.json",
    ]  # fmt: skip


def test_unreadable_or_unknown_task_folder_is_an_error(tmp_path, tiny, monkeypatch):
    ds, _ = tiny
    data = tmp_path / "ds"
    for task in ("rod", "wrench"):
        (data / task).mkdir(parents=True)
        for f in (ds / task).iterdir():
            (data / task / f.name).write_bytes(f.read_bytes())
    real_scandir = os.scandir

    def scandir(path="."):
        if Path(path) == data / "wrench":
            raise PermissionError(13, "Permission denied", str(path))
        return real_scandir(path)

    monkeypatch.setattr(os, "scandir", scandir)  # (as root, chmod 000 does not stop reading)
    with pytest.raises(DataError, match="wrench: cannot read the task folder: Permission denied"):
        load_dataset(data)
    monkeypatch.undo()
    (data / "notes").mkdir()
    (data / "notes" / "todo.txt").write_text("x")
    with pytest.raises(DataError, match="notes: field 'format': cannot detect.*leading '_'"):
        load_dataset(data)
    (data / "notes").rename(data / "_notes")
    assert load_dataset(data).tasks == ["rod", "wrench"]
    (data / "zz").symlink_to(tmp_path / "nowhere")
    with pytest.raises(DataError, match="broken link"):
        load_dataset(data)


# ------------------------------------------------------------ (5) one line, exit 2
def _bad_settings(tmp_path: Path, old: str, new: str | bytes) -> str:
    text = ROBOT_FILE.read_text()
    assert old in text
    path = tmp_path / "robot.toml"
    if isinstance(new, bytes):
        path.write_bytes(text.replace(old, "").encode() + new)
    else:
        path.write_text(text.replace(old, new))
    return str(path)


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:  # argparse's refusal of an argument (one usage line, one error line)
        return int(exc.code)


ACC = "acceleration_rad_s2 = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]"
MOUNT = "mount_offset_m = [0.001252, -0.001573, -0.010144]"
STEP = "collision_max_step_rad = 0.1"


def _argv(case: str, tmp_path: Path, tiny, afile: Path) -> list[str]:
    ds, model = tiny
    out = ["--out", str(tmp_path / "out")]
    base = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--no-preview"]
    robot = {
        "velocity 1e-9": (ACC, ACC + "\nvelocity_rad_s = 1e-9"),
        "collision step 1e-12": (STEP, "collision_max_step_rad = 1e-12"),
        "mount offset 1e300": (MOUNT, "mount_offset_m = [1e300, 0, 0]"),
        "binary settings": ("schema_version = 1", b"\xff\xfe\x00"),
    }
    if case in robot:
        return [*base, *out, "--robot", _bad_settings(tmp_path, *robot[case])]
    if case in ("rate_hz 1e9 in the file", "frames of numbers"):
        line = "rate_hz = 1e9" if case.startswith("rate") else "frames = [1, 2]"
        pipe = tmp_path / "p.toml"
        pipe.write_text(f"[data]\n{line}\n")
        return ["run", str(pipe), "--model", str(model), *out]
    return {
        "pipeline is a folder": ["run", str(tmp_path), *out],
        "--out is a file": [*base, "--out", str(afile)],
        "--out under a file": [*base, "--out", str(afile / "sub")],
        "--save-model is a folder": [*base[:4], "--save-model", str(tmp_path), *out],
        "--rate 1e9": [*base, *out, "--rate", "1e9"],
        "--rate 1e-9": [*base, *out, "--rate", "1e-9"],
        "--port 70000": ["preview", str(PIPELINE), "--port", "70000"],
        "--port 0": ["preview", str(PIPELINE), "--port", "0"],
        "--speed 0": ["preview", str(PIPELINE), "--speed", "0"],
        "--ratio 1.5": [*base, *out, "--ratio", "1.5"],
        "--model is a folder": [*base[:4], "--model", str(tmp_path), *out],
        "train --out is a folder": ["train", str(ds), "--out", str(tmp_path)],
        "train --coupling bogus": ["train", str(ds), "--out", str(tmp_path / "m.npz"), "--coupling", "bogus"],
        "evaluate --json under a file": ["evaluate", str(ds), "--json", str(afile / "r.json")],
        "evaluate --jobs 0": ["evaluate", str(ds), "--jobs", "0"],
        "evaluate --n-test 0": ["evaluate", str(ds), "--n-test", "0"],
        "preview --html is a folder": ["preview", str(PIPELINE), "--html", str(tmp_path)],
        "synth into a file": ["synth", str(afile)],
    }[case]


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("pipeline is a folder", "is a folder, not a pipeline file"),
        ("--out is a file", "it is a file"),
        ("--out under a file", "is a file, not a folder"),
        ("--save-model is a folder", "it is a folder"),
        ("velocity 1e-9", "velocity_rad_s.*implausible value 1e-09"),
        ("collision step 1e-12", "collision_max_step_rad.*implausible"),
        ("mount offset 1e300", "mount_offset_m.*implausible"),
        ("binary settings", "not valid TOML"),
        ("--rate 1e9", "control_rate_hz.*\\[1, 1000\\] Hz"),
        ("--rate 1e-9", "control_rate_hz"),
        ("rate_hz 1e9 in the file", "data.rate_hz"),
        ("frames of numbers", "data.frames.*list of names"),
        ("--port 70000", "outside 1-65535"),
        ("--port 0", "outside 1-65535"),
        ("--speed 0", "outside \\(0"),
        ("--ratio 1.5", "outside \\(0, 1\\]"),
        ("--model is a folder", "is a folder, not a model file"),
        ("train --out is a folder", "it is a folder"),
        ("train --coupling bogus", "coupling"),
        ("evaluate --json under a file", "is a file, not a folder"),
        ("evaluate --jobs 0", "outside \\[1, 1024\\]"),
        ("evaluate --n-test 0", "outside \\[1, inf\\]"),
        ("preview --html is a folder", "it is a folder"),
        ("synth into a file", "it is a file"),
    ],
)
def test_bad_paths_and_values_give_one_line_and_exit_2(tmp_path, tiny, capsys, case, message):
    afile = tmp_path / "a_file"
    afile.write_text("keep")
    argv = _argv(case, tmp_path, tiny, afile)
    t0 = time.perf_counter()
    assert _exit_code(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert "error:" in last and re.search(message, last), err
    assert afile.read_text() == "keep"
    assert not (tmp_path / "out").exists()
    assert time.perf_counter() - t0 < 60  # refused before any large computation (a hang guard)


def test_absurd_limits_are_refused_before_allocating():
    names = tuple(f"j{i}" for i in range(3))
    limits = JointLimits(
        lower_rad=np.full(3, -3.0),
        upper_rad=np.full(3, 3.0),
        velocity_rad_s=np.full(3, 1e-9),
        acceleration_rad_s2=np.ones(3),
        jerk_rad_s3=np.full(3, 10.0),
        joint_names=names,
    )
    path = np.linspace([0.0, 0.0, 0.0], [1.0, -1.0, 0.5], 50)
    with pytest.raises(InfeasibleError, match=f"at least 1e\\+09 s .*more than {MAX_TRAJECTORY_SAMPLES}"):
        time_path(path, limits, rate_hz=100.0)
    slow = dataclasses.replace(limits, velocity_rad_s=np.full(3, 1.0), acceleration_rad_s2=np.full(3, 1e-12))
    with pytest.raises(InfeasibleError, match="acceleration 1e-12"):
        time_path(path, slow, rate_hz=100.0)


# --------------------------------------------------------- (6) rejected samples leave no trace
@pytest.fixture(scope="module")
def streaming_model():
    ds = random_dataset(9, n_tasks=2, n_demos=5, dims={"a": 2, "emg": 3})
    for demos in ds.demos.values():  # EMG-like channels: positive, modelled in log space
        for k, d in enumerate(demos):
            demos[k] = dataclasses.replace(d, groups={**d.groups, "emg": np.exp(d.groups["emg"])})
    model = IProMP(["a", "emg"], n_basis=9, noise=10.0, log_groups=["emg"]).fit(ds)
    obs = ds.demos["task1"][0].head(0.4, ["a", "emg"])
    return model, obs


def _feed(stream, obs, i):
    return stream.update(float(obs.t[i]), {g: obs.groups[g][i] for g in ("a", "emg")})


BAD_SAMPLES = [
    ("a", 1e200),
    ("a", -1e200),
    ("a", 1e308),
    ("a", np.inf),
    ("a", np.nan),
    ("a", 1e30),
    ("emg", 1e200),
    ("emg", 1e300),
    ("emg", -1e200),
    ("emg", 1e30),
    ("emg", np.inf),
    ("a", "abc"),
    ("emg", None),  # a whole group given as a wrong type below
]


@pytest.mark.parametrize(("group", "value"), BAD_SAMPLES)
def test_rejected_stream_sample_leaves_the_stream_as_it_was(streaming_model, group, value):
    model, obs = streaming_model
    reference = model.stream()
    for i in range(obs.n_samples):
        expected = _feed(reference, obs, i)
    stream = model.stream()
    for i in range(obs.n_samples):
        if i == 4:
            sample = {
                g: obs.groups[g][i].astype(object if isinstance(value, str) else float) for g in ("a", "emg")
            }
            if value is None:
                sample[group] = {"not": "numbers"}
            else:
                sample[group][1] = value
            with pytest.raises(ObservationError, match=group):
                stream.update(float(obs.t[i]) - 1e-4, sample)
        result = _feed(stream, obs, i)
    assert stream.n_samples == obs.n_samples
    np.testing.assert_allclose(result.posterior, expected.posterior, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.alpha, expected.alpha, rtol=0, atol=1e-12)


@pytest.mark.parametrize("bad", [("t", "abc"), ("t", None), ("sample", None), ("sample", [1, 2])])
def test_malformed_stream_calls_are_refused(streaming_model, bad):
    model, obs = streaming_model
    stream = model.stream()
    t, sample = 0.0, {g: obs.groups[g][0] for g in ("a", "emg")}
    if bad[0] == "t":
        t = bad[1]
    else:
        sample = bad[1]
    with pytest.raises(ObservationError):
        stream.update(t, sample)
    assert stream.n_samples == 0


# ------------------------------------------------------------------------ (7) live preview
@pytest.fixture(scope="module")
def live():
    from ipromp_pin.preview import LivePreview, PreviewContent

    robot = load_robot("baxter_left")
    q = np.tile([0.0, -0.5, 0.0, 1.0, 0.0, 0.5, 0.0], (5, 1))
    content = PreviewContent(
        model=robot.model, visual_model=None, collision_model=robot.collision_model, t_s=np.arange(5) * 0.1,
        q=q, joint_names=robot.joint_names, q_full=robot.full_configuration(q[0]), ee_mean=np.zeros((5, 3)),
        task="a", tasks=["a", "b"], posterior=np.array([0.5, 0.5]),
    )  # fmt: skip
    server = LivePreview(content, port=0)
    yield server
    server.close()


@pytest.mark.parametrize(
    ("host", "allowed"),
    [
        ("localhost", True),
        ("127.0.0.1", True),
        ("LOCALHOST:{port}", True),
        ("127.0.0.1:{port}", True),
        ("evil.example.com", False),
        ("attacker.test:{port}", False),
        ("127.0.0.1.nip.io:{port}", False),
        ("localhost.evil.com", False),
        ("", False),
    ],
)
def test_live_preview_answers_local_host_names_only(live, host, allowed):
    for path in ("/", "/ws"):
        conn = http.client.HTTPConnection("127.0.0.1", live.port, timeout=5)
        conn.putrequest("GET", path, skip_host=True)
        conn.putheader("Host", host.format(port=live.port))
        conn.endheaders()
        status = conn.getresponse().status
        conn.close()
        if path == "/":
            assert (status == 200) == allowed, (host, status)
        else:  # a plain GET of the websocket: refused by the Host check, else by the missing upgrade
            assert status == 403 if not allowed else status == 400


def test_abrupt_websocket_disconnects_are_quiet(live, capfd, caplog):
    caplog.set_level(logging.DEBUG)
    for _ in range(5):
        s = socket.create_connection(("127.0.0.1", live.port))
        s.sendall(
            (
                f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{live.port}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        s.recv(10)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        s.close()  # a reset in the middle of the scene transfer
    time.sleep(0.3)
    for p in (0.3, 0.6, 0.9):
        live.update_posterior(np.array([p, 1 - p]))
    time.sleep(0.5)
    err = capfd.readouterr().err + "\n".join(r.getMessage() + str(r.exc_info or "") for r in caplog.records)
    assert "Traceback" not in err and "WebSocketClosedError" not in err and "StreamClosedError" not in err
    assert live.n_clients == 0


# ----------------------------------------------------------- (8) progress and error lines
def test_progress_only_on_a_terminal_and_errors_on_their_own_line(tmp_path, tiny, capsys, monkeypatch):
    ds, _ = tiny
    assert main(["train", str(ds), "--out", str(tmp_path / "m.npz")]) == 0
    assert capsys.readouterr().err == ""  # not a terminal: no progress, no carriage returns
    bad = tmp_path / "ds"
    for task in ("rod", "wrench"):
        (bad / task).mkdir(parents=True)
        for f in sorted((ds / task).iterdir()):
            (bad / task / f.name).write_bytes(f.read_bytes())
    (bad / "wrench" / "wrench_002.npz").write_text("garbage")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["train", str(bad), "--out", str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err
    assert "\r[5/8] wrench/wrench_000" in err  # progress shown on a terminal
    error_line = err.split("\n")[-2]
    assert error_line.startswith("ipromp-pin train: error: ") and "wrench_002.npz" in error_line


# ------------------------------------------------------------------- outputs.dir semantics
def test_outputs_dir_is_relative_to_the_pipeline_file(tmp_path, tiny, monkeypatch):
    ds, model = tiny
    folder = tmp_path / "pipelines"
    folder.mkdir()
    pipe = folder / "p.toml"
    pipe.write_text(f'[data]\ndataset = "{ds}"\n[model]\nload = "{model}"\n[outputs]\ndir = "results"\n'
                    "preview_html = false\n")  # fmt: skip
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert load_pipeline(pipe).out_dir == folder / "results"
    assert main(["run", str(pipe)]) == 0
    assert (folder / "results" / "trajectory.csv").exists() and not (elsewhere / "results").exists()
    # --out on the command line is relative to the current folder
    assert main(["run", str(pipe), "--out", "here"]) == 0
    assert (elsewhere / "here" / "trajectory.csv").exists()
    # the shipped definition (empty outputs.dir) writes ./out, never into the package
    assert load_pipeline(PIPELINE).out_dir == Path("out")
    assert load_pipeline("baxter_handover").out_dir == Path("out")
