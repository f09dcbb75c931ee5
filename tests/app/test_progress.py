"""Progress: one line rewritten in place on a terminal, plain lines in a log (first, last, every tenth
and every 10 s); a command's error on its own line after them."""

from __future__ import annotations

import sys

from ipromp_pin.app import main
from ipromp_pin.app.progress import ProgressLine


def test_progress_only_on_a_terminal_and_errors_on_their_own_line(tmp_path, tiny, capsys, monkeypatch):
    ds, _ = tiny
    assert main(["train", str(ds), "--out", str(tmp_path / "m.npz")]) == 0
    err = capsys.readouterr().err  # not a terminal: plain lines, no carriage returns
    assert "\r" not in err and "\033" not in err
    lines = err.splitlines()
    assert lines[0].startswith("[1/8] ") and lines[-1].startswith("[8/8] ") and len(lines) == 8
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


def test_progress_in_a_log_prints_every_nth_step_and_every_ten_seconds(capsys):
    now = [0.0]
    line = ProgressLine(tty=False, clock=lambda: now[0])
    for done in range(1, 101):
        now[0] = done * 0.01 if done < 50 else 0.5 + (done - 50) * 3.0  # fast, then 3 s a step
        line(done, 100, f"demo {done}")
    err = capsys.readouterr().err
    assert "\r" not in err
    shown = [int(ln.split("/")[0][1:]) for ln in err.splitlines()]
    # the first; every 10th while fast; then at least every 10 s (every 4th step at 3 s a step); the last
    assert shown[:6] == [1, 11, 21, 31, 41, 51] and shown[-1] == 100
    assert all(b - a <= 10 for a, b in zip(shown, shown[1:], strict=False))
    assert {55, 59} <= set(shown)
    assert err.splitlines()[-1] == "[100/100] demo 100  (150 s)"
