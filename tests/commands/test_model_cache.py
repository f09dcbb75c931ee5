"""The cache of trained models: a hit is the same model, anything that changes the fit is a miss."""

from __future__ import annotations

import dataclasses
from functools import partial

import numpy as np
import pytest

from ipromp_pin.cli import main
from ipromp_pin.commands.model_cache import fit_cached, training_key
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, load_robot


@pytest.fixture(scope="module")
def demos():
    return make_synthetic_dataset(n_tasks=2, n_demos=6, seed=3).all_demos()


@pytest.fixture(scope="module")
def fk():
    return partial(ee_positions, load_robot("baxter_left"))


def _small() -> IProMP:
    return IProMP(n_basis=9, noise=1.0, temperature=1.0, condition_noise=1.0, head=False, coupling="all")


def test_a_hit_is_the_same_model_without_training(tmp_path, demos, fk, monkeypatch):
    first, source = fit_cached(_small(), demos[1:], fk, tmp_path)
    assert source is None and len(list(tmp_path.glob("*.npz"))) == 1

    def refuse(*args, **kwargs):
        raise AssertionError("a cache hit must not train")

    monkeypatch.setattr(IProMP, "fit", refuse)
    second, source = fit_cached(_small(), demos[1:], fk, tmp_path)
    assert source is not None and source.parent == tmp_path
    p1, p2 = first.predict(demos[0].head(0.4)), second.predict(demos[0].head(0.4))
    for name in ("log_posterior", "alpha", "q_mean", "q_cov"):
        assert np.array_equal(getattr(p1, name), getattr(p2, name)), name


def test_anything_the_fit_reads_changes_the_key(demos, fk):
    key = training_key(_small(), demos, fk)
    assert key == training_key(_small(), list(demos), fk)
    changed = demos[2].groups["emg"].copy()
    changed[5, 1] += 1e-9
    other = dataclasses.replace(demos[2], groups={**demos[2].groups, "emg": changed})
    variants = {
        "a sample": training_key(_small(), [*demos[:2], other, *demos[3:]], fk),
        "a parameter": training_key(_small().set_params(n_basis=10), demos, fk),
        "the demos": training_key(_small(), demos[1:], fk),
        "no kinematics": training_key(_small(), demos, None),
        "other kinematics": training_key(_small(), demos, lambda q: fk(q) + [0.0, 0.0, 0.01]),
    }
    assert all(v is not None and v != key for v in variants.values()), variants
    assert len(set(variants.values())) == len(variants)


def test_kinematics_that_fail_are_not_cached(tmp_path, demos):
    def broken(q):
        raise ValueError("no robot")

    assert training_key(_small(), demos, broken) is None


def test_a_corrupt_entry_is_trained_again_and_replaced(tmp_path, demos):
    fit_cached(_small(), demos, None, tmp_path)
    (entry,) = tmp_path.glob("*.npz")
    entry.write_bytes(b"not a model")
    model, source = fit_cached(_small(), demos, None, tmp_path)
    assert source is None and model.tasks_ == sorted({d.task for d in demos})
    _, source = fit_cached(_small(), demos, None, tmp_path)
    assert source == entry


def test_an_unwritable_cache_only_means_no_caching(tmp_path, demos):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    model, source = fit_cached(_small(), demos, None, blocker / "models")
    assert source is None and model.tasks_


def test_the_cache_keeps_the_most_recent_entries(tmp_path, demos, monkeypatch):
    monkeypatch.setattr("ipromp_pin.commands.model_cache.MAX_ENTRIES", 2)
    for n_basis in (7, 8, 9):
        fit_cached(_small().set_params(n_basis=n_basis), demos, None, tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 2
    _, source = fit_cached(_small().set_params(n_basis=9), demos, None, tmp_path)
    assert source is not None


def test_run_reuses_the_model_and_retrain_trains(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path / "cache"))
    args = ["run", "pipelines/baxter_handover.toml", "--no-preview", "--no-rosbag"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert "[model] trained on" in capsys.readouterr().out
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert "[model] reused the model" in capsys.readouterr().out
    assert main([*args, "--out", str(tmp_path / "c"), "--retrain"]) == 0
    assert "[model] trained on" in capsys.readouterr().out
    a, b, c = ((tmp_path / x / "trajectory.csv").read_text() for x in "abc")
    assert a == b == c
