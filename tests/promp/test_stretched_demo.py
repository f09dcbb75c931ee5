"""A training set whose slowest demo lasts far longer than the others (a slow partner, a pause)
trains: the recognition head's held-out rows that no other demo's phase range explains are left out,
with a warning naming the demo, instead of ending the fit."""

from __future__ import annotations

import dataclasses

import pytest

from ipromp_pin.promp import IProMP
from ipromp_pin.promp.selection import UnexplainedRowsWarning
from ipromp_pin.readers.synthetic import make_synthetic_dataset


def test_a_demo_twice_as_long_as_the_others_is_trained_on_with_a_warning():
    data = make_synthetic_dataset(n_tasks=3, n_demos=6, seed=5)
    train = [d for task in data.tasks for d in data.demos[task][:-1]]
    slow = train[0]
    train[0] = dataclasses.replace(slow, t=slow.t * 2.5, duration_s=None, name=slow.name + "_slow")
    with pytest.warns(UnexplainedRowsWarning, match=f"of {slow.task}/{slow.name}_slow\\)"):
        model = IProMP(observe=["orientation", "emg"], noise=10.0, handover=False).fit(train)
    assert model.head_ is not None  # the head is fitted on the rows that remain
    held = [data.demos[task][-1].head(0.2, groups=model.observe_) for task in data.tasks]
    assert [p.task for p in model.predict(held)] == list(data.tasks)
