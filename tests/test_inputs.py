"""Bounded inputs (issue 24, item 11): every user file is a regular file of bounded size and nesting,
every count is bounded, a degenerate dataset and a mistyped schema version get one line, and
native CSV columns are read by name."""

from __future__ import annotations

import io
import os
import signal
import zipfile
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import PIPELINE, ROBOT_FILE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.readers.native import read_demo, write_demo
from ipromp_pin.readers.synthetic import make_synthetic_dataset


@pytest.fixture
def watchdog():
    """Fail instead of hanging: SIGALRM after 60 s."""

    def hang(signum, frame):
        raise AssertionError("the command blocked (no bound on its input)")

    previous = signal.signal(signal.SIGALRM, hang)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _special(tmp_path: Path, kind: str, name: str = "input.toml") -> Path:
    path = tmp_path / name
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev_zero":
        path = Path("/dev/zero")
    elif kind == "folder":
        path.mkdir()
    elif kind == "huge":
        path.write_bytes(b"# padding\n" * 200_000)
    elif kind == "deep_array":
        path.write_text("x = " + "[" * 20000 + "]" * 20000 + "\n")
    elif kind == "deep_table":
        path.write_text("x = " + "{a = " * 20000 + "1" + "}" * 20000 + "\n")
    elif kind == "binary":
        path.write_bytes(b"\xff\xfe\x00garbage")
    return path


KINDS = ["fifo", "dev_zero", "folder", "huge", "deep_array", "deep_table", "binary"]
PROBLEMS = {
    "fifo": "named pipe (FIFO)",
    "dev_zero": "character device",
    "folder": "folder",
    "huge": "too large",
    "deep_array": "nested too deeply",
    "deep_table": "nested too deeply",
    "binary": "not UTF-8",
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("where", ["pipeline", "robot", "limits", "objects"])
def test_unbounded_or_special_input_files_are_refused_in_one_line(
    tiny, tmp_path, capsys, watchdog, kind, where
):
    if kind == "dev_zero" and not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    bad = _special(tmp_path, kind)
    ds, model = tiny
    if where == "pipeline":
        args = ["run", str(bad), "--out", str(tmp_path / "out")]
    elif where == "robot":
        args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--robot", str(bad),
                "--out", str(tmp_path / "out")]  # fmt: skip
    elif where == "objects":
        args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--objects", str(bad),
                "--out", str(tmp_path / "out")]  # fmt: skip
    else:
        args = ["replay", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--limits", str(bad),
                "--out", str(tmp_path / "out"), "--no-preview"]  # fmt: skip
    assert main(args) == 2
    line = one_error_line(capsys.readouterr().err)
    assert str(bad) in line
    if kind != "folder" or where != "pipeline":  # a pipeline folder has its own message
        assert PROBLEMS[kind] in line, line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["fifo", "folder", "deep_header"])
def test_a_special_or_deeply_nested_model_file_is_refused(tiny, tmp_path, capsys, watchdog, kind):
    ds, model = tiny
    if kind == "deep_header":
        bad = tmp_path / "deep.npz"
        with zipfile.ZipFile(model) as src, zipfile.ZipFile(bad, "w") as dst:
            for info in src.infolist():
                data = src.read(info)
                if info.filename == "header.npy":
                    buf = io.BytesIO()
                    np.save(buf, np.array('{"a": ' * 50000 + "1" + "}" * 50000))
                    data = buf.getvalue()
                dst.writestr(info.filename, data)
    else:
        bad = _special(tmp_path, kind, "model.npz")
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(bad), "--out", str(tmp_path / "o")]
    assert main([*args, "--no-preview"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert str(bad) in line


def test_a_demo_that_is_a_fifo_is_refused(tmp_path, watchdog):
    from ipromp_pin.exceptions import DataError

    os.mkfifo(tmp_path / "demo.csv")
    with pytest.raises(DataError, match="named pipe"):
        read_demo(tmp_path / "demo.csv")


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--splits", "1000000000"], "--splits"),
        (["--splits", "1001"], "--splits"),
        (["--n-test", "1e9"], "--n-test"),
        (["--n-train", "10000000"], "--n-train"),
        (["--seed", "99999999999999999999"], "--seed"),
    ],
)
def test_counts_are_bounded(tiny, capsys, args, field):
    ds, _ = tiny
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", str(ds), "--protocol", "splits", *args])
    assert exc.value.code == 2
    assert field in capsys.readouterr().err


@pytest.mark.parametrize("value", ['"1"', "1.0", "true", "[1]", "2"])
def test_schema_version_of_another_type_or_value_says_what_is_read(tiny, tmp_path, capsys, value):
    robot = tmp_path / "robot.toml"
    robot.write_text(ROBOT_FILE.read_text().replace("schema_version = 1", f"schema_version = {value}"))
    ds, model = tiny
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--robot", str(robot)]
    assert main([*args, "--out", str(tmp_path / "o"), "--no-preview"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "field 'schema_version'" in line
    if value == "2":
        assert "unsupported version 2 (this code reads 1)" in line
    else:
        assert "must be the integer 1" in line and "(this code reads 1)" not in line


def _dataset(folder: Path, layout: str) -> Path:
    demos = make_synthetic_dataset(n_tasks=2, n_demos=3, seed=2).demos
    a, b = list(demos)
    for i in range(3):
        if layout == "one recording per task":
            write_demo(demos[a][0], folder / a / f"d{i}.npz")
            write_demo(demos[b][i], folder / b / f"d{i}.npz")
        else:  # both tasks hold the same demos
            write_demo(demos[a][i], folder / a / f"d{i}.npz")
            write_demo(demos[a][i], folder / b / f"d{i}.npz")
    return folder


@pytest.mark.parametrize(
    ("layout", "problem"),
    [
        ("one recording per task", "demos are all the same recording"),
        ("the same demos in two tasks", "hold the same demos: they cannot be told apart"),
    ],
)
def test_a_degenerate_dataset_is_refused_before_training(tmp_path, capsys, layout, problem):
    ds = _dataset(tmp_path / "ds", layout)
    assert main(["train", str(ds), "--out", str(tmp_path / "m.npz")]) == 2
    assert problem in one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "m.npz").exists()


@pytest.mark.parametrize(
    "order",
    [
        ["hand_position.2", "hand_position.0", "hand_position.1"],
        ["hand_position.1", "hand_position.2", "hand_position.0"],
    ],
)
def test_native_csv_extras_are_read_by_name(tmp_path, order):
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=1).all_demos()[0]
    path = write_demo(demo, tmp_path / "t" / "a.csv") or tmp_path / "t" / "a.csv"
    lines = Path(path).read_text().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    rows = [ln.split(",") for ln in lines if not ln.startswith("#")]
    header = rows[0]
    cols = [header.index(f"extras:{name}") for name in order]
    rest = [j for j in range(len(header)) if j not in cols]
    reordered = [",".join(r[j] for j in rest + cols) for r in rows]
    other = tmp_path / "t" / "b.csv"
    other.write_text("\n".join(comments + reordered) + "\n")
    a, b = read_demo(path), read_demo(other)
    np.testing.assert_array_equal(a.extras["hand_position"], b.extras["hand_position"])
    np.testing.assert_array_equal(a.groups["orientation"], b.groups["orientation"])


def test_native_csv_extras_numbered_with_a_gap_are_refused(tmp_path):
    from ipromp_pin.exceptions import DataError

    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=1).all_demos()[0]
    path = tmp_path / "a.csv"
    write_demo(demo, path)
    path.write_text(path.read_text().replace("extras:hand_position.2", "extras:hand_position.5"))
    with pytest.raises(DataError, match=r"extras:hand_position.*numbered"):
        read_demo(path)
