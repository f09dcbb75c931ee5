"""Fixtures of the planning tests: one model of synthetic Baxter hand-overs for the closed-loop tests."""

from __future__ import annotations

import pytest

from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot

OBSERVE = ["orientation", "emg"]


@pytest.fixture(scope="session")
def synthetic_closed_loop():
    """A model trained on synthetic Baxter hand-overs (all but the last demo of each of 3 tasks), the
    robot, the training demos and the held-out last demo of each task."""
    ds = make_synthetic_dataset(n_tasks=3, n_demos=8, seed=3)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    model = IProMP(observe=OBSERVE).fit(train)
    return model, load_robot("baxter_left"), train, test
