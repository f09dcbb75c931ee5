"""Models are checked after fitting, before saving and after loading; bad model files are refused
cheaply, naming the file and the array (issue classes 1 and 4)."""

from __future__ import annotations

import dataclasses
import json
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError, ModelError, ModelFileError
from ipromp_pin.promp import IProMP


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> tuple[IProMP, Path]:
    model = IProMP(["a", "b"], n_basis=9, noise=10.0, coupling="all").fit(random_dataset(5, n_demos=5))
    path = tmp_path_factory.mktemp("model") / "m.npz"
    model.save(path)
    return model, path


def _arrays(path: Path) -> tuple[dict, dict]:
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return arrays, json.loads(str(arrays["header"][()]))


def _write(path: Path, arrays: dict, header: dict) -> Path:
    arrays = dict(arrays, header=np.array(json.dumps(header)))
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def _first(a: np.ndarray, value: float) -> np.ndarray:
    a = a.astype(float).copy()
    a.reshape(-1)[int(np.flatnonzero(np.isfinite(a.reshape(-1)))[0])] = value
    return a


ARRAY_EDITS = [
    ("task0_diag", lambda a: _first(a, np.nan), "task 'task0' diag: 1 NaN"),
    ("task0_diag", lambda a: _first(a, -1.0), "task 'task0' diag: zero or negative"),
    ("task1_diag", lambda a: _first(a, 1e300), "task 'task1' diag: implausible value 1e\\+300"),
    ("task0_factor", lambda a: _first(a, np.inf), "task 'task0' factor: 1 NaN or infinite"),
    ("task2_mean", lambda a: _first(a, 1e300), "task 'task2' mean: implausible"),
    ("task0_train_weights", lambda a: _first(a, np.nan), "train_weights"),
    ("task0_train_alpha", lambda a: _first(a, 0.0), "train_alpha: zero or negative"),
    ("task0_alpha_grid", lambda a: a[::-1].copy(), "alpha_grid: phase candidates must be increasing"),
    ("task0_alpha_grid", lambda a: _first(a, np.nan), "alpha_grid"),
    ("task0_alpha_log_prior", lambda a: a - 1.0, "alpha_log_prior: probabilities sum to"),
    ("task0_shrinkage", lambda a: a + 2.0, "shrinkage: intensities must lie in"),
    ("task_log_prior", lambda a: _first(a, 0.0), "task_log_prior: probabilities sum to"),
    ("scaler_scale", lambda a: _first(a, 0.0), "scaler_scale: zero or negative"),
    ("scaler_scale", lambda a: _first(a, 1e300), "scaler_scale: implausible"),
    ("scaler_offset", lambda a: _first(a, np.inf), "scaler_offset"),
    ("residual_var", lambda a: _first(a, -1.0), "residual_var: negative"),
    ("task0_diag", lambda a: a[:-1], "task0_diag.npy' has shape"),
    ("task1_train_alpha", lambda a: a[:-1], "train_alpha: has shape"),
    ("task0_factor", lambda a: a[:, :-1], "task0_factor.npy' has shape"),
    ("task0_diag", lambda a: np.ones(a.shape, dtype=np.int64), "holds int64, not float64"),
    ("task0_diag", lambda a: np.array(["x"] * a.size), "not float64"),
    ("residual_var", lambda a: a[:, None], "residual_var.npy' has shape"),
]


@pytest.mark.parametrize(("key", "edit", "message"), ARRAY_EDITS)
def test_tampered_arrays_are_refused(tmp_path, saved, key, edit, message):
    _, path = saved
    arrays, header = _arrays(path)
    arrays[key] = edit(arrays[key])
    bad = _write(tmp_path / "bad.npz", arrays, header)
    with pytest.raises(ModelFileError, match=message) as info:
        IProMP.load(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


HEADER_EDITS = [
    (lambda h: h.update(noise_ratio=-1.0), "noise_ratio"),
    (lambda h: h.update(noise_ratio=float("inf")), "noise_ratio"),
    (lambda h: h.update(duration_nominal_s=0.0), "duration_nominal_s"),
    (lambda h: h.update(duration_nominal_s=1e300), "duration_nominal_s"),
    (lambda h: h["task_scalars"][0].update(alpha_sigma=-0.1), "alpha_sigma"),
    (lambda h: h["task_scalars"][0].update(alpha_mu=float("nan")), "alpha_mu"),
    (lambda h: h.update(tasks=[h["tasks"][0]] * 3), "tasks"),
    (lambda h: h.update(coupled_groups=["nope"]), "coupled"),
    (lambda h: h["params"].update(n_points=10**9), "n_points"),
    (lambda h: h["params"].update(n_points="many"), "n_points"),
    (lambda h: h["params"].update(n_basis=10**9), "n_basis"),
    (lambda h: h["params"].update(n_basis=10), "shape"),
    (lambda h: h["params"].update(blas_threads="many"), "blas_threads"),
    (lambda h: h["params"].update(task_prior={"task0": -1.0}), "task_prior"),
    (lambda h: h["params"].update(surprise=1), "unknown model parameters"),
    (lambda h: h.update(surprise=1), "unknown header fields"),
    (lambda h: h["channel_names"].update(b=["b0", "b0", "b2"]), "distinct"),
    (lambda h: h.update(format_version="1"), "format_version"),
]


@pytest.mark.parametrize(("edit", "message"), HEADER_EDITS)
def test_tampered_headers_are_refused(tmp_path, saved, edit, message):
    _, path = saved
    arrays, header = _arrays(path)
    edit(header)
    bad = _write(tmp_path / "bad.npz", arrays, header)
    with pytest.raises(ModelFileError, match=message):
        IProMP.load(bad)


def test_unknown_array_is_refused(tmp_path, saved):
    _, path = saved
    arrays, header = _arrays(path)
    arrays["task7_mean"] = arrays["task0_mean"]
    with pytest.raises(ModelFileError, match="unknown array 'task7_mean.npy'"):
        IProMP.load(_write(tmp_path / "bad.npz", arrays, header))


def _append_zeros_member(path: Path, name: str, n_bytes: int) -> None:
    """Add a deflated .npy member of ``n_bytes`` zeros (a file of a few hundred kB)."""
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as zf:
        with zf.open(name, "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(
                fh, {"descr": "<f8", "fortran_order": False, "shape": (n_bytes // 8,)}
            )
            chunk = bytes(1 << 20)
            for _ in range(n_bytes >> 20):
                fh.write(chunk)


@pytest.mark.parametrize("name", ["junk.npy", "task0_train_weights.npy"])
def test_oversized_member_is_refused_without_loading_it(tmp_path, saved, name):
    _, path = saved
    arrays, header = _arrays(path)
    arrays.pop(name[:-4], None)
    bad = _write(tmp_path / "bad.npz", arrays, header)
    _append_zeros_member(bad, name, 200 << 20)  # 200 MB of zeros
    assert bad.stat().st_size < 2e6
    tracemalloc.start()
    try:
        with pytest.raises(ModelFileError, match="unknown array|expands"):
            IProMP.load(bad)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6  # megabytes, not the member's 200 MB


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p.write_bytes(b""), "not a readable model file"),
        (lambda p: p.write_text("hello"), "not a readable model file"),
        (lambda p: p.mkdir(), "is a folder"),
    ],
)
def test_files_that_are_not_models_are_refused(tmp_path, make, message):
    path = tmp_path / "x.npz"
    make(path)
    with pytest.raises(ModelFileError, match=message):
        IProMP.load(path)


def test_model_is_checked_before_saving_and_a_failed_save_keeps_the_old_file(tmp_path, saved):
    model, path = saved
    target = tmp_path / "m.npz"
    target.write_bytes(path.read_bytes())
    broken = IProMP(**model.get_params())
    tm = model.fitted_.models["task0"]
    bad_task = dataclasses.replace(tm, diag=np.full_like(tm.diag, np.nan))
    broken._set_fitted(dataclasses.replace(model.fitted_, models={**model.fitted_.models, "task0": bad_task}))
    with pytest.raises(ModelError, match="task 'task0' diag"):
        broken.save(target)
    assert target.read_bytes() == path.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]


@pytest.mark.parametrize(("group", "value"), [("a", 1e300), ("a", -1e200), ("robot", 1e300), ("robot", 1e13)])
@pytest.mark.parametrize("noise", [10.0, "auto"])
def test_training_on_absurd_data_is_refused(group, value, noise):
    # demos built in code skip the readers' plausibility checks: training refuses them itself
    ds = random_dataset(7, n_tasks=2, n_demos=4)
    demo = ds.demos["task0"][1]
    values = demo.groups[group].copy()
    values[3:, 0] = value  # a sensor that ran away (finite, absurd)
    ds.demos["task0"][1] = dataclasses.replace(demo, groups={**demo.groups, group: values})
    with pytest.raises(DataError, match="implausible training value") as info:
        IProMP(["a", "b"], n_basis=9, noise=noise).fit(ds)
    assert info.value.source == demo.source and info.value.field.startswith(f"{group}/")


def test_round_trip_still_exact(tmp_path, saved):
    model, path = saved
    loaded = IProMP.load(path)
    obs = random_dataset(5, n_demos=5).demos["task1"][0].head(0.3, ["a", "b"])
    assert isinstance(obs, Demo)
    a, b = model.predict(obs), loaded.predict(obs)
    assert np.array_equal(a.q_mean, b.q_mean) and np.array_equal(a.log_posterior, b.log_posterior)
