"""Progress lines on a terminal only; a command's error on its own line after them."""

from __future__ import annotations

import sys

from ipromp_pin.app import main


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
