"""The command lines of ``docs/your_data.md`` run as pasted, after its Python blocks made ``mydata``
(issue 24, items 12 and 15): ``train --holdout`` then ``run --model`` on the held-out demo, without
the warning that it was in the training set."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from ipromp_pin.app import main

DOCS = Path(__file__).resolve().parents[1] / "docs"


def blocks(page: Path, language: str) -> list[str]:
    """The code blocks of one language of a Markdown page."""
    return re.findall(rf"^```{language}\n(.*?)^```", page.read_text(), flags=re.MULTILINE | re.DOTALL)


def test_your_data_commands_run_as_pasted(tmp_path, monkeypatch, capsys):
    page = DOCS / "your_data.md"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "docs_your_data"}
    for i, block in enumerate(blocks(page, "python")):
        exec(compile(block, f"your_data.md block {i + 1}", "exec"), namespace)  # noqa: S102
    commands = [ln for b in blocks(page, "bash") for ln in b.splitlines() if ln.startswith("ipromp-pin ")]
    assert any("--holdout" in c for c in commands)
    capsys.readouterr()
    for command in commands:
        assert main(shlex.split(command)[1:]) == 0, command
    err = capsys.readouterr().err
    assert "training set" not in err, err
    assert (tmp_path / "model.npz").is_file() and (tmp_path / "out" / "trajectory.csv").is_file()
