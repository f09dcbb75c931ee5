"""Model files: exact round trip and clear errors for bad files."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.exceptions import ModelFileError, NotFittedError
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.serialization import FORMAT_VERSION


@pytest.fixture(scope="module")
def model_and_obs():
    train, test = split(random_dataset(21, missing_group="b"), 6)
    model = IProMP(["a", "b"], n_basis=9, n_alpha=50, task_prior={"task0": 0.5, "task1": 0.3, "task2": 0.2})
    return model.fit(train), test["task1"][0].head(0.3, ["a", "b"])


def test_round_trip_gives_identical_predictions(tmp_path: Path, model_and_obs) -> None:
    model, obs = model_and_obs
    path = tmp_path / "model.npz"
    model.save(path)
    loaded = IProMP.load(path)
    assert loaded.tasks_ == model.tasks_ and loaded.noise_ratio_ == model.noise_ratio_
    assert loaded.cv_scores_ == model.cv_scores_
    a, b = model.predict(obs), loaded.predict(obs)
    for name in ("log_posterior", "alpha", "q_mean", "q_cov", "q_prior_mean", "phase_log_post", "t"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.human_mean["b"], b.human_mean["b"])
    z = np.linspace(0, 1, 7)
    assert np.array_equal(model.distribution("task2", z)[0], loaded.distribution("task2", z)[0])


def test_file_has_no_pickled_objects(tmp_path: Path, model_and_obs) -> None:
    model, _ = model_and_obs
    path = tmp_path / "m.npz"
    model.save(path)
    with np.load(path, allow_pickle=False) as npz:
        header = json.loads(str(npz["header"][()]))
        assert all(npz[name].dtype != object for name in npz.files)
    assert header["format"] == "ipromp_pin.IProMP" and header["format_version"] == FORMAT_VERSION == 8
    assert header["tasks"] == ["task0", "task1", "task2"]


def test_version_1_file_loads_as_the_model_it_was(tmp_path: Path, model_and_obs) -> None:
    """A version-1 file (no temperature, conditioning noise ratio or head) predicts as a version-2
    model with temperature 1, the conditioning at the recognition's noise ratio and no head."""
    model, obs = model_and_obs
    model.save(tmp_path / "m.npz")

    def as_v1(h: dict) -> None:
        for key in ("temperature", "condition_noise_ratio", "condition_cv_scores", "head", "handover"):
            h.pop(key)
        h.pop("handover_cv_scores")
        for key in ("temperature", "condition_noise", "head", "handover"):
            h["params"].pop(key)
        h["format_version"] = 1

    with np.load(tmp_path / "m.npz", allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files if not k.startswith(("head_", "handover_"))}
    header = json.loads(str(arrays["header"][()]))
    as_v1(header)
    arrays["header"] = np.array(json.dumps(header))
    np.savez(tmp_path / "v1.npz", **arrays)
    old = IProMP.load(tmp_path / "v1.npz")
    assert old.head_ is None and old.temperature_ == 1.0
    assert old.condition_noise_ratio_ == old.noise_ratio_ == model.noise_ratio_
    assert old.handover_ is None
    same = IProMP(
        **{
            **model.get_params(),
            "head": False,
            "handover": False,
            "temperature": 1.0,
            "condition_noise": "same",
        }
    )
    fitted = model.fitted_
    from dataclasses import replace

    same._set_fitted(replace(fitted, head=None, handover=None, temperature=1.0, condition_noise_ratio=None))
    a, b = old.predict(obs), same.predict(obs)
    for name in ("log_posterior", "alpha", "q_mean", "q_cov"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def _rewrite_header(src: Path, dst: Path, change) -> None:
    with np.load(src, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    header = json.loads(str(arrays["header"][()]))
    change(header)
    arrays["header"] = np.array(json.dumps(header))
    np.savez(dst, **arrays)


def test_newer_format_version_is_refused(tmp_path: Path, model_and_obs) -> None:
    model, _ = model_and_obs
    model.save(tmp_path / "m.npz")
    _rewrite_header(tmp_path / "m.npz", tmp_path / "new.npz", lambda h: h.update(format_version=99))
    with pytest.raises(ModelFileError, match="version 99 is newer"):
        IProMP.load(tmp_path / "new.npz")


def test_truncated_file_is_refused(tmp_path: Path, model_and_obs) -> None:
    model, _ = model_and_obs
    model.save(tmp_path / "m.npz")
    data = (tmp_path / "m.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError, match="cut.npz"):
        IProMP.load(tmp_path / "cut.npz")


def test_missing_array_is_refused(tmp_path: Path, model_and_obs) -> None:
    model, _ = model_and_obs
    model.save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files if k != "task1_factor"}
    np.savez(tmp_path / "broken.npz", **arrays)
    with pytest.raises(ModelFileError, match="corrupt"):
        IProMP.load(tmp_path / "broken.npz")


@pytest.mark.parametrize("kind", ["text", "other_npz", "wrong_format", "zip"])
def test_files_that_are_not_models_are_refused(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "x.npz"
    if kind == "text":
        path.write_text("hello")
    elif kind == "other_npz":
        np.savez(path, a=np.zeros(3))
    elif kind == "wrong_format":
        np.savez(path, header=np.array(json.dumps({"format": "something.else", "format_version": 1})))
    else:
        with zipfile.ZipFile(path, "w") as zf:
            zf.writestr("readme.txt", "not numpy")
    with pytest.raises(ModelFileError):
        IProMP.load(path)


def test_missing_file_and_unfitted_model(tmp_path: Path) -> None:
    with pytest.raises(ModelFileError, match="not found"):
        IProMP.load(tmp_path / "none.npz")
    with pytest.raises(NotFittedError):
        IProMP(["a"]).save(tmp_path / "u.npz")


def test_model_remembers_its_training_demos_and_version_1_files_still_load(tmp_path: Path, model_and_obs):
    model, obs = model_and_obs
    train, test = split(random_dataset(21, missing_group="b"), 6)
    assert [(r.task, r.name) for r in model.trained_on_] == [(d.task, d.name) for d in train.all_demos()]
    assert len({r.sha256 for r in model.trained_on_}) == len(model.trained_on_)  # one digest per demo
    path = tmp_path / "model.npz"
    model.save(path)
    loaded = IProMP.load(path)
    assert loaded.trained_on_ == model.trained_on_
    header = json.loads(str(np.load(path)["header"][()]))
    assert (
        header["format_version"] == FORMAT_VERSION
        and header["trained_on"][0]["sha256"] == model.trained_on_[0].sha256
    )

    # a version-1 file (no trained_on) loads, predicts the same, and says it does not know its demos
    def to_v1(h: dict) -> None:
        h["format_version"] = 1
        del h["trained_on"]

    old = tmp_path / "v1.npz"
    _rewrite_header(path, old, to_v1)
    v1 = IProMP.load(old)
    assert v1.trained_on_ is None
    assert np.array_equal(v1.predict(obs).q_mean, model.predict(obs).q_mean)


def test_human_fit_round_trips_and_version_6_files_load_without_it(tmp_path: Path, model_and_obs):
    model, obs = model_and_obs
    record = {
        "version": 1,
        "translation_m": [0.01, -0.02, 0.0],
        "stature_m": None,
        "parts": [["chest", 3, 0.05]],
    }
    path = tmp_path / "model.npz"
    model.with_human_fit(record).save(path)
    loaded = IProMP.load(path)
    assert loaded.human_fit_ == record
    assert np.array_equal(loaded.predict(obs).q_mean, model.predict(obs).q_mean)

    def to_v6(h: dict) -> None:
        h["format_version"] = 6
        del h["human_fit"]

    old = tmp_path / "v6.npz"
    _rewrite_header(path, old, to_v6)
    assert IProMP.load(old).human_fit_ is None  # not measured

    def not_an_object(h: dict) -> None:
        h["human_fit"] = [1, 2]

    bad = tmp_path / "bad.npz"
    _rewrite_header(path, bad, not_an_object)
    with pytest.raises(ModelFileError, match="human_fit"):
        IProMP.load(bad)
