"""The code examples of the documentation run as they are: every ``python`` block of a page, in order,
in one namespace per page, in a fresh working folder."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
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
