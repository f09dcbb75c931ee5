"""The cache of trained models: a hit is the same model, anything that changes the fit is a miss."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from functools import partial

import numpy as np
import pytest

from ipromp_pin.app import main
from ipromp_pin.app.model_cache import fit_cached, training_key, verify_entry
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
    monkeypatch.setattr("ipromp_pin.app.model_cache.MAX_ENTRIES", 2)
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


def _swap_entry(tmp_path, demos, how: str) -> None:
    """Tamper with the single cache entry of ``fit_cached(_small(), demos[1:])`` in ``tmp_path``."""
    (entry,) = tmp_path.glob("*.npz")
    other = tmp_path / "other"
    if how in ("other demos", "other demos and sidecar"):
        fit_cached(_small(), demos[2:], None, other)
    elif how == "other settings":
        fit_cached(_small().set_params(n_basis=8), demos[1:], None, other)
    if how == "no sidecar":
        entry.with_suffix(".json").unlink()
        return
    if how == "sidecar of another key":
        side = entry.with_suffix(".json")
        side.write_text(side.read_text().replace(entry.stem, "0" * 64))
        return
    (copied,) = other.glob("*.npz")
    entry.write_bytes(copied.read_bytes())
    if how in ("other demos and sidecar", "other settings"):  # a consistent-looking record beside it
        entry.with_suffix(".json").write_text(
            json.dumps(
                {"cache": 1, "key": entry.stem, "sha256": hashlib.sha256(entry.read_bytes()).hexdigest()}
            )
        )


@pytest.mark.parametrize(
    ("how", "why"),
    [
        ("other demos", "not the one stored under its key"),
        ("other demos and sidecar", "of these 11 were not in its training (e.g. "),
        ("other settings", "trained with other settings"),
        ("no sidecar", "no readable record of the key"),
        ("sidecar of another key", "names another key"),
    ],
)
def test_a_cache_entry_that_is_not_what_it_claims_is_rebuilt_with_one_line(tmp_path, demos, how, why):
    first, _ = fit_cached(_small(), demos[1:], None, tmp_path)
    _swap_entry(tmp_path, demos, how)
    lines: list[str] = []
    model, source = fit_cached(_small(), demos[1:], None, tmp_path, log=lines.append)
    assert source is None and len(lines) == 1 and why in lines[0] and "training again" in lines[0]
    assert [r.sha256 for r in model.trained_on_] == [r.sha256 for r in first.trained_on_]
    p1, p2 = first.predict(demos[0].head(0.4)), model.predict(demos[0].head(0.4))
    assert np.array_equal(p1.q_mean, p2.q_mean)
    lines.clear()  # the rebuilt entry is verified and used
    _, source = fit_cached(_small(), demos[1:], None, tmp_path, log=lines.append)
    assert source is not None and not lines


def test_verifying_an_entry_costs_a_few_ms(tmp_path, demos):
    import time

    fit_cached(_small(), demos[1:], None, tmp_path)
    (entry,) = tmp_path.glob("*.npz")
    key = entry.stem
    cached = IProMP.load(entry)
    t0 = time.perf_counter()
    for _ in range(5):
        assert verify_entry(entry, key, _small(), cached, demos[1:]) == ""
    assert (time.perf_counter() - t0) / 5 < 0.05  # measured about 2 ms; generous on a busy machine
