"""Interruptions (issue 24, item 10): SIGINT and SIGTERM at any stage exit 130 / 143 with one line,
leave the earlier outputs and no temporary file."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers_cli import run_tiny

from ipromp_pin import atomic
from ipromp_pin.app import main
from ipromp_pin.outputs import staging
from ipromp_pin.promp import IProMP

ROOT = Path(__file__).resolve().parents[2]
SIGNALS = [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")]


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _no_temporary(folder: Path) -> None:
    left = [p.name for p in folder.rglob("*") if ".partial" in p.name or ".previous" in p.name]
    assert not left, left


def _one_line(err: str, name: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning: ")]
    lines = [ln for ln in lines if not re.match(r"\[\d+/\d+\] ", ln)]  # progress lines (no terminal)
    assert "Traceback" not in err and len(lines) == 1, err
    assert f"interrupted ({name})" in lines[0]


@pytest.mark.parametrize(("sig", "status", "name"), SIGNALS)
@pytest.mark.parametrize("stage", ["bag", "report", "commit"])
def test_interrupted_while_writing_outputs(tiny, tmp_path, capsys, monkeypatch, sig, status, name, stage):
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--ros1-bag") == 0
    before = _snapshot(out)
    capsys.readouterr()
    if stage == "bag":
        original = staging.write_ros1_bag

        def interrupted_bag(content, path):
            original(content, path)
            os.kill(os.getpid(), sig)
            time.sleep(1)  # the handler runs here

        monkeypatch.setattr(staging, "write_ros1_bag", interrupted_bag)
    elif stage == "report":

        def interrupted_report(*args, **kwargs):
            os.kill(os.getpid(), sig)
            time.sleep(1)

        monkeypatch.setattr("ipromp_pin.plans.files.stage_report", interrupted_report)
    else:  # in the middle of the renames of the commit
        calls = []
        original_replace = os.replace

        def interrupted_replace(src, dst):
            calls.append(dst)
            original_replace(src, dst)
            if len(calls) == 3:
                os.kill(os.getpid(), sig)
                time.sleep(1)

        monkeypatch.setattr(atomic.os, "replace", interrupted_replace)
    assert run_tiny(tiny, out, "--ros1-bag", "--ratio", "0.6") == status
    monkeypatch.undo()
    _one_line(capsys.readouterr().err, name)
    assert _snapshot(out) == before
    _no_temporary(out)


@pytest.mark.parametrize(("sig", "status", "name"), SIGNALS)
def test_interrupted_training_keeps_the_earlier_model(tiny, tmp_path, capsys, monkeypatch, sig, status, name):
    ds, model = tiny
    target = tmp_path / "model.npz"
    target.write_bytes(model.read_bytes())
    original = IProMP.fit

    def interrupted_fit(self, *args, **kwargs):
        os.kill(os.getpid(), sig)
        time.sleep(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(IProMP, "fit", interrupted_fit)
    assert main(["train", str(ds), "--out", str(target)]) == status
    _one_line(capsys.readouterr().err, name)
    assert target.read_bytes() == model.read_bytes()
    _no_temporary(tmp_path)


def test_handlers_are_restored_after_a_command(tiny, tmp_path):
    before = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    assert main(["synth", str(tmp_path / "d"), "--tasks", "1", "--demos", "2"]) == 0
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


@pytest.mark.parametrize(("sig", "status", "name"), SIGNALS)
@pytest.mark.parametrize("delay", [1.0, 2.5])
def test_console_script_interrupted_at_start_up_or_in_training(tiny, tmp_path, sig, status, name, delay):
    ds, model = tiny
    target = tmp_path / "model.npz"
    target.write_bytes(model.read_bytes())
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "ipromp_pin.app", "train", str(ds), "--out", str(target)],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    time.sleep(delay)
    proc.send_signal(sig)
    err = proc.communicate(timeout=120)[1]
    if proc.returncode == 0:  # finished before the signal on a fast machine: nothing to check
        pytest.skip("the command finished before the signal")
    # 130 / 143, or (seen on a loaded machine, after the one line was printed) the interpreter ending
    # itself with the signal, which a shell reports as the same 128 + signal
    assert proc.returncode in (status, -sig)
    _one_line(err, name)
    assert target.read_bytes() == model.read_bytes()
    _no_temporary(tmp_path)


@pytest.mark.parametrize("chain", ["context", "cause"])
def test_an_error_raised_because_of_an_interruption_is_the_interruption(monkeypatch, capsys, chain):
    import ipromp_pin.app as cli

    def interrupted_inside_a_library(argv, seen):
        seen.append("train")
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            if chain == "cause":
                raise RuntimeError("worker failed") from exc
            raise RuntimeError("worker failed")  # noqa: B904 (the context is the point)

    monkeypatch.setattr(cli, "_main", interrupted_inside_a_library)
    assert cli.main([]) == 130
    assert "ipromp-pin train: interrupted (SIGINT)" in capsys.readouterr().err

    def plain_error(argv, seen):
        raise RuntimeError("a bug, not an interruption")

    monkeypatch.setattr(cli, "_main", plain_error)
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main([])


def test_an_interruption_a_ctypes_callback_swallows_is_raised_after_it():
    import ctypes

    from ipromp_pin.app.interrupt import interruptible

    def callback() -> None:
        raise KeyboardInterrupt  # as the signal handler does inside a compiler's callback

    call = ctypes.CFUNCTYPE(None)(callback)
    hook = sys.unraisablehook
    with pytest.raises(KeyboardInterrupt), interruptible():
        call()  # ctypes cannot raise it: reported as unraisable, then sent again
        for _ in range(100):  # handled between two bytecodes of the command's own code
            time.sleep(0.001)
    assert sys.unraisablehook is hook  # restored


def test_after_the_command_a_late_signal_leaves_its_exit_status(tmp_path):
    code = (
        "import os, signal, sys\n"
        "from ipromp_pin.app.interrupt import ignore_late_signals\n"
        "ignore_late_signals()\n"
        "os.kill(os.getpid(), signal.SIGINT); os.kill(os.getpid(), signal.SIGTERM)\n"
        "sys.exit(3)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 3
