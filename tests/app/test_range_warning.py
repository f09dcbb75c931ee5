"""An observation far outside everything the model was trained on gets a warning naming the channel
group and how far out it is (issue 24, item 7)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from helpers_cli import PIPELINE

from ipromp_pin.app import main
from ipromp_pin.plans.warnings import range_warnings
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.inputs import RANGE_WARNING_SD, group_distance_sd
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.native import write_demo
from ipromp_pin.readers.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def model(tiny):
    return IProMP.load(tiny[1])


def test_demos_like_the_training_data_get_no_warning(model, tiny):
    fresh = make_synthetic_dataset(n_tasks=3, n_demos=8, seed=21).all_demos()
    for d in [*load_dataset(tiny[0]).all_demos(), *fresh]:
        assert range_warnings(model, d) == [], d.name
        assert all(
            group_distance_sd(model.fitted_, g, d.groups[g]) < RANGE_WARNING_SD / 1.5 for g in model.observe_
        )


@pytest.mark.parametrize(
    ("group", "change"),
    [
        ("emg", lambda v: v * 0.001),
        ("emg", lambda v: v * 0.05),
        ("emg", lambda v: v * 1000.0),
        ("emg", lambda v: v + 500.0),
        ("orientation", lambda v: v * 5.0),
        ("orientation", lambda v: v[:, ::-1].copy()),
    ],
)
def test_an_observation_far_outside_the_training_data_is_named(model, group, change):
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=21).all_demos()[0]
    bad = dataclasses.replace(demo, groups={**demo.groups, group: change(demo.groups[group])})
    [warning] = range_warnings(model, bad)
    d = group_distance_sd(model.fitted_, group, bad.groups[group])
    assert d > RANGE_WARNING_SD
    assert f"the observed '{group}' lies {d:.1f} standard deviations" in warning and "\n" not in warning


def test_run_on_emg_in_other_units_warns_and_reports_it(tiny, tmp_path, capsys):
    ds, model = tiny
    other = tmp_path / "ds"
    for d in load_dataset(ds).all_demos():
        write_demo(
            dataclasses.replace(d, groups={**d.groups, "emg": d.groups["emg"] * 0.001}),
            other / d.task / f"{d.name}.npz",
        )
    out = tmp_path / "out"
    args = [
        "run",
        str(PIPELINE),
        "--dataset",
        str(other),
        "--model",
        str(model),
        "--out",
        str(out),
        "--no-preview",
    ]
    main(args)
    err = capsys.readouterr().err
    assert "warning: the observed 'emg' lies" in err
    report = json.loads((out / "report.json").read_text())
    assert any("the observed 'emg' lies" in w for w in report["warnings"])
    assert np.isfinite(report["predicted_duration_s"])


def test_occluded_samples_are_ignored_without_a_runtime_warning(model, recwarn):
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=21).all_demos()[0]
    values = demo.groups["orientation"].copy()
    clean = group_distance_sd(model.fitted_, "orientation", values)
    values[::2] = np.nan  # every other sample occluded (a tracked frame that was not seen)
    assert group_distance_sd(model.fitted_, "orientation", values) == pytest.approx(clean, rel=0.3)
    assert group_distance_sd(model.fitted_, "orientation", np.full_like(values, np.nan)) == 0.0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
