"""Observation windows in seconds: the cut does not depend on the recording's length, and
``evaluate`` keys its cells by the window (a fraction of each test demo, seconds, or a fraction of
the training demos' mean length)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipromp_pin.data import Dataset
from ipromp_pin.evaluation.evaluate import EvaluationConfig, evaluate, to_markdown
from ipromp_pin.evaluation.run import window_cells
from ipromp_pin.evaluation.splits import split_paper
from ipromp_pin.evaluation.tables import to_json
from ipromp_pin.evaluation.windows import FitWindow, Window
from ipromp_pin.exceptions import DataError, ObservationError
from ipromp_pin.readers.synthetic import make_synthetic_dataset

TINY_MODEL = {"n_basis": 9, "n_alpha": 8, "head": False, "handover": False, "coupling": "all", "noise": 3.0}


@pytest.fixture(scope="module")
def synthetic() -> Dataset:
    return make_synthetic_dataset(n_tasks=2, n_demos=7, seed=3)


def test_a_window_in_seconds_cuts_at_the_same_sample_whatever_the_length(synthetic):
    demo = synthetic.all_demos()[0]
    shorter = demo.slice(int(0.6 * demo.n_samples))  # the same motion, recorded for less time
    seconds = FitWindow.of(Window("seconds", 0.5))
    a, b = seconds.cut(demo), seconds.cut(shorter)
    assert a.n_samples == b.n_samples and a.t[-1] == b.t[-1]
    assert a.t[-1] - a.t[0] <= 0.5 < a.t[-1] - a.t[0] + (demo.t[1] - demo.t[0])
    np.testing.assert_array_equal(a.groups["emg"], b.groups["emg"])
    # a fraction of the recording's own length moves with that length
    ratio = FitWindow.of(0.2)
    assert ratio.cut(demo).n_samples != ratio.cut(shorter).n_samples
    # a fraction of the training demos' mean length is a time too: it ignores the test demo's length
    of_train = Window("train_fraction", 0.25).for_fit(2.0)
    assert of_train.end_s == 0.5
    assert of_train.cut(demo).n_samples == of_train.cut(shorter).n_samples == a.n_samples
    assert seconds.fraction(demo) == pytest.approx(0.5 / demo.duration_s)


def test_windows_out_of_range_are_refused_in_one_line():
    for kind, value in (("seconds", 0.0), ("seconds", 601.0), ("train_fraction", 1.5), ("ratio", -0.1)):
        with pytest.raises(DataError, match="window"):
            Window(kind, value)
    with pytest.raises(DataError, match="unknown kind"):
        Window("minutes", 1.0)


def test_window_cells_pair_every_fraction_with_its_window_in_seconds():
    grid = [(10, 0.1), (10, 0.2)]
    assert window_cells(grid, "fraction") == grid
    assert window_cells(grid) == [
        *grid,
        (10, Window("train_fraction", 0.1)),
        (10, Window("train_fraction", 0.2)),
    ]
    assert window_cells(grid, "seconds", seconds=[0.4]) == [(10, Window("seconds", 0.4))]
    with pytest.raises(DataError, match="--windows both or seconds"):
        window_cells(grid, "fraction", seconds=[0.4])


def test_evaluate_keys_its_cells_by_the_window_in_seconds(synthetic):
    grid = [(5, 0.2), (5, Window("seconds", 0.5)), (5, Window("train_fraction", 0.2))]
    cfg = EvaluationConfig(
        protocol="paper", observe=[["orientation", "emg"]], grid=grid, n_test=2, model_params=TINY_MODEL
    )
    cells = evaluate(synthetic, cfg, robot=None)
    assert [c.window["kind"] for c in cells] == ["ratio"] * 2 + ["seconds"] * 2 + ["train_fraction"] * 2
    train, test = split_paper(synthetic, n_train=5, n_test=2)
    nominal = float(np.mean([d.t[-1] - d.t[0] for d in train]))
    for c in cells:
        if c.window_kind == "ratio":
            assert c.obs_ratio == 0.2 and c.window["seconds"] is None and c.observed_fraction == 0.2
            continue
        assert c.obs_ratio is None
        end = 0.5 if c.window_kind == "seconds" else 0.2 * nominal
        assert c.window["seconds"] == pytest.approx(end)
        # every test demo observed up to the same time, whatever its length
        assert end - 0.05 < c.observed_s <= end
        lengths = [d.duration_s for d in test if d.task == c.task]
        assert c.observed_fraction == pytest.approx(
            float(np.median([c.observed_s / n for n in lengths])), rel=0.1
        )
    md = to_markdown(cells)
    assert "| 5 | 0.5 s | orientation+emg |" in md
    assert f"0.2 of train ({0.2 * nominal:.2f} s)" in md
    doc = json.loads(json.dumps(to_json(cells)))
    assert {c["window"]["kind"] for c in doc["cells"]} == {"ratio", "seconds", "train_fraction"}


def test_a_window_leaving_fewer_than_2_samples_is_refused_before_any_fit(synthetic):
    cfg = EvaluationConfig(
        protocol="paper",
        observe=[["emg"]],
        grid=[(5, Window("seconds", 0.001))],
        n_test=2,
        model_params=TINY_MODEL,
    )
    with pytest.raises(ObservationError, match="fewer than 2 samples"):
        evaluate(synthetic, cfg, robot=None)
