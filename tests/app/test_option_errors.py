"""Errors that blame the right place: a bad value typed on the command line is reported against its
option (not the pipeline file's field), with the closest known name for a mistyped option, command,
choice, task or channel group; ``ipromp-pin --version``."""

from __future__ import annotations

import json
import shutil

import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.version import __version__


def _refused(argv: list[str], capsys) -> str:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own refusals
        code = int(exc.code or 0)
    captured = capsys.readouterr()
    assert code == 2, captured
    return one_error_line(captured.err)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--task", "rood"],
            "command line: option '--task': unknown task 'rood'; did you mean 'rod'? (rod, ",
        ),
        (
            ["--task", "tape", "--demo", "20"],
            "command line: option '--demo': index 20 out of range for 20 demos",
        ),
        (
            ["--observe", "orientaton,emg"],
            "command line: option '--observe': channel group 'orientaton' not in the data; "
            "did you mean 'orientation'? (has: acc, emg, orientation)",
        ),
    ],
)
def test_a_bad_value_on_the_command_line_names_its_option(tmp_path, capsys, args, expected):
    line = _refused(["run", str(PIPELINE), "--out", str(tmp_path / "o"), "--no-preview", *args], capsys)
    assert expected in line
    assert "baxter_handover.toml" not in line and "observation." not in line
    assert not (tmp_path / "o").exists()


def test_a_bad_value_in_the_file_still_names_the_files_field(tmp_path, capsys):
    pipe = tmp_path / "p.toml"
    pipe.write_text('[observation]\ntask = "wrenc"\n')
    line = _refused(["run", str(pipe), "--out", str(tmp_path / "o"), "--no-preview"], capsys)
    assert f"{pipe}: field 'observation.task': unknown task 'wrenc'; did you mean 'wrench'?" in line


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (
            ["run", str(PIPELINE), "--tsk", "rod"],
            "ipromp-pin run: error: unrecognized arguments: --tsk rod; "
            "did you mean --task? (see ipromp-pin run --help)",
        ),  # fmt: skip
        (
            ["evaluate", "x", "--protocl", "paper", "--obsrve", "emg"],
            "--protocl: did you mean --protocol?; --obsrve: did you mean --observe?",
        ),  # fmt: skip
        (["rn", "x"], "invalid choice: 'rn'; did you mean 'run'? (choose from 'run'"),
        (["run", str(PIPELINE), "--xyzzy"], "unrecognized arguments: --xyzzy (see ipromp-pin run --help)"),
    ],
)
def test_a_mistyped_option_or_command_gets_the_closest_name(capsys, argv, expected):
    assert expected in _refused(argv, capsys)


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"ipromp-pin {__version__}"


def test_another_dataset_without_the_pipelines_task_observes_its_first_task(tiny, tmp_path, capsys):
    ds = tmp_path / "ds"
    shutil.copytree(tiny[0], ds)
    (ds / "wrench").rename(ds / "bottle")  # the shipped pipeline observes 'wrench' of its own demos
    argv = ["run", str(PIPELINE), "--dataset", str(ds), "--no-preview", "--no-retreat"]
    main([*argv, "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert f"the pipeline's task 'wrench' is not in {ds}: observing its first task, 'bottle'" in out
    assert json.loads((tmp_path / "o" / "report.json").read_text())["observation"]["task"] == "bottle"
    # a task typed on the command line is still the user's: refused, naming the option
    line = _refused([*argv, "--out", str(tmp_path / "p"), "--task", "wrench"], capsys)
    assert "command line: option '--task': unknown task 'wrench'" in line
