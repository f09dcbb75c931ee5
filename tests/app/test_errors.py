"""Bad paths and values on the command line: one error line, exit 2, nothing written, no long
computation first."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from helpers_cli import PIPELINE, ROBOT_FILE

from ipromp_pin.app import main


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
        "evaluate --window-s 0": ["evaluate", str(ds), "--window-s", "0"],
        "evaluate --window-s 1e9": ["evaluate", str(ds), "--window-s", "1e9"],
        "evaluate --window-s 0.001": [
            "evaluate",
            str(ds),
            "--window-s",
            "0.001",
            "--grid",
            "full",
            "--n-train",
            "3",
        ],
        "evaluate --windows fraction --window-s": [
            "evaluate",
            str(ds),
            "--windows",
            "fraction",
            "--window-s",
            "1",
        ],
        "--until-s 0": [*base, *out, "--until-s", "0"],
        "--ratio and --until-s": [*base, *out, "--ratio", "0.2", "--until-s", "0.5"],
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
        ("binary settings", "not a valid TOML"),
        ("--rate 1e9", "option '--rate'.*\\[1, 1000\\] Hz"),
        ("--rate 1e-9", "option '--rate'"),
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
        ("evaluate --n-test 0", "outside \\[1, 100000\\]"),
        ("evaluate --window-s 0", "--window-s.*outside \\(0, 600\\]"),
        ("evaluate --window-s 1e9", "--window-s.*outside \\(0, 600\\]"),
        ("evaluate --window-s 0.001", "0.001 s.*fewer than 2 samples"),
        ("evaluate --windows fraction --window-s", "--windows both or seconds"),
        ("--until-s 0", "--until-s.*outside \\(0, 600\\]"),
        ("--ratio and --until-s", "not allowed with argument --ratio"),
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
