"""The code examples of the documentation and the README run as they are: every ``python`` block of a
page, in order, in one namespace per page, in a fresh working folder."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = ["api.md", "your_data.md"]


def code_blocks(page: Path) -> list[str]:
    """The ``python`` code blocks of a Markdown page."""
    return re.findall(r"^```python\n(.*?)^```", page.read_text(), flags=re.MULTILINE | re.DOTALL)


@pytest.mark.parametrize("page", PAGES)
def test_docs_examples_run(page, tmp_path, monkeypatch, capsys):
    blocks = code_blocks(DOCS / page)
    assert blocks
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": f"docs_{page}"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{page} block {i + 1}", "exec"), namespace)  # noqa: S102
    assert capsys.readouterr().out  # the examples print what they show


def test_readme_python_example_runs_as_pasted(datasets_dir, tmp_path, monkeypatch):
    """The README's example reads ``../shared/datasets`` as seen from a checkout: run it in a fresh
    folder that has the datasets at that place, so it writes nothing into the project."""
    blocks = code_blocks(ROOT / "README.md")
    assert blocks
    work = tmp_path / "checkout"
    work.mkdir()
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "datasets").symlink_to(datasets_dir)
    monkeypatch.chdir(work)
    namespace: dict = {"__name__": "readme"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"README.md block {i + 1}", "exec"), namespace)  # noqa: S102
    assert (work / "out" / "model.npz").is_file()
    assert namespace["via"].q_mean.shape == namespace["pred"].q_mean.shape
