"""A task whose demos reach the hand-over on different branches of the arm's inverse kinematics is
named at training (``MixedBranchesWarning``); demos of one branch are not."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from ipromp_pin.app.synth import on_robot
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.branches import MixedBranchesWarning, mixed_branch_tasks
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ROBOTS_DIR, ee_positions, load_robot


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """A UR5 without its gripper at (0.3, 0.2, 0.1) m, where the synthetic demos retargeted to it
    reach some hand-overs on other branches (elbow, wrist) than the rest of their task's."""
    text = (ROBOTS_DIR / "ur5.toml").read_text()
    text = re.sub(r"(?ms)^\[tool\]\n.*?(?=^\[)", "", text)
    path = tmp_path_factory.mktemp("ur5") / "ur5_mixed.toml"
    path.write_text(text.replace("xyz_m = [0.10, 0.20, 0.10]", "xyz_m = [0.30, 0.20, 0.10]"))
    robot = load_robot(path)
    return robot, on_robot(make_synthetic_dataset(n_demos=10, seed=1), str(path))


def last_samples(ds) -> dict[str, np.ndarray]:
    """Task -> (N, J) its demos' last robot samples (complete in these demos)."""
    return {task: np.stack([d.groups["robot"][-1] for d in demos]) for task, demos in ds.demos.items()}


def test_demos_on_two_branches_are_found_and_one_branch_is_not(mixed):
    robot, ds = mixed
    found = mixed_branch_tasks(last_samples(ds), lambda q: ee_positions(robot, q))
    assert [t for t, _, _ in found] == ["rod", "wrench", "tape"]
    assert all(offset > 3.0 * spread for _, offset, spread in found)
    baxter = load_robot("baxter_left")
    one = make_synthetic_dataset(n_demos=10, seed=1)
    assert mixed_branch_tasks(last_samples(one), lambda q: ee_positions(baxter, q)) == []
    ur5 = load_robot("ur5")  # at its placement with its gripper: one branch per task
    assert mixed_branch_tasks(last_samples(on_robot(one, "ur5")), lambda q: ee_positions(ur5, q)) == []


def test_training_on_them_warns_naming_the_task(mixed):
    robot, ds = mixed
    demos = [d for task in ("rod", "tape") for d in ds.demos[task][:6]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        IProMP(observe=["orientation", "emg"]).fit(demos, fk=lambda q: ee_positions(robot, q))
    said = [str(w.message) for w in caught if issubclass(w.category, MixedBranchesWarning)]
    assert len(said) == 2 and all(re.search(r"different branches", m) for m in said)
    assert said[0].startswith("task 'rod': ") and said[1].startswith("task 'tape': ")
    assert all(w.filename == __file__ for w in caught if issubclass(w.category, MixedBranchesWarning))


@pytest.mark.realdata
def test_the_recorded_baxter_demos_lie_on_one_branch(chen2017_dir, handover2017_dir):
    baxter = load_robot("baxter_left")
    for folder in (chen2017_dir, handover2017_dir):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = load_dataset(folder)
        assert np.isfinite(np.concatenate(list(last_samples(ds).values()))).all()
        assert mixed_branch_tasks(last_samples(ds), lambda q: ee_positions(baxter, q)) == []
