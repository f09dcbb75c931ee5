"""The code examples of the documentation and the README run as they are: every ``python`` block of a
page, in order, in one namespace per page, in a fresh working folder."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ipromp_pin import IProMP
from ipromp_pin.robot import load_robot_settings

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


def on_six_joints(block: str) -> str | None:
    """An api.md block as it runs on a UR5 (6 joints): its demos recorded on the UR5 (the synthetic
    demos retargeted through the gripper, as ``ipromp-pin synth --robot ur5`` writes them) and the
    UR5 where Baxter is named; ``None`` for the block that executes Baxter's model on a UR5 (there
    the model is the UR5's own) and for the grid search, which scores the recognition only (the
    arm's joints are fitted as in the first block) and is the page's slowest block. The goal-pose
    block runs: at the UR5's placement with its gripper every task's demos lie on one branch of its
    inverse kinematics (at its earlier placement without the gripper they did not,
    tests/promp/test_branches.py)."""
    if 'robot="ur5"' in block or "GridSearchCV(" in block:
        return None
    synthetic = "make_synthetic_dataset(n_demos=10, seed=1)"
    assert synthetic in block or "make_synthetic_dataset(" not in block
    return block.replace(synthetic, f'on_robot({synthetic}, "ur5")').replace('"baxter_left"', '"ur5"')


def test_the_api_examples_run_on_a_six_joint_arm(tmp_path, monkeypatch, capsys):
    from ipromp_pin.app.synth import on_robot

    blocks = [b for b in map(on_six_joints, code_blocks(DOCS / "api.md")) if b is not None]
    assert any("condition_on_goal_pose(" in b and '"ur5"' in b for b in blocks)  # the goal pose on the UR5
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "docs_api_ur5", "on_robot": on_robot}
    for i, block in enumerate(blocks):
        exec(compile(block, f"api.md (UR5) block {i + 1}", "exec"), namespace)  # noqa: S102
    assert capsys.readouterr().out
    assert namespace["model"].joint_names_ == load_robot_settings("ur5").recorded_arm_joints
    assert namespace["plan"].trajectory.q.shape[1] == 6 and namespace["samples"].shape[2] == 6


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
    assert namespace["pred"].task in namespace["model"].tasks_
    assert IProMP.load(work / "out" / "model.npz").tasks_ == namespace["model"].tasks_
