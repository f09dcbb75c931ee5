"""The hand-over regression fused into the robot's prediction (ipromp_pin.promp.handover)."""

from __future__ import annotations

import json
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.data import ROBOT, Dataset, Demo
from ipromp_pin.exceptions import ModelFileError
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.handover import (
    RATIOS,
    TRUST_GRID,
    HandoverRegression,
    fit_knn,
    fit_ridge,
    knn_predict,
    neighbour_arrays,
    readouts,
)
from ipromp_pin.promp.serialization import FORMAT_VERSION
from ipromp_pin.promp.window import WindowSummary


def fk(q: np.ndarray) -> np.ndarray:
    """A smooth nonlinear stand-in for the kinematics: (n, 3) joint angles -> (n, 3) positions."""
    q = np.atleast_2d(q)
    x = np.sin(q[:, 0]) + 0.5 * q[:, 1]
    return np.stack([x, np.cos(q[:, 1]) * q[:, 2], 0.3 * q[:, 0] + np.sin(q[:, 2])], 1)


def informative_dataset(seed: int = 2, n_demos: int = 23, step: bool = False) -> Dataset:
    """One task whose robot ends at a linear function of a per-demo offset ``h`` of the human's four
    channels (visible from the start of the window), while both also move by independent smooth
    wiggles (the robot's vanish at the end): the weights' covariance, estimated from 15 demos, holds
    much variance besides the coupling, which a regression on the window's mean and last value
    sees directly. With ``step`` the robot's end moves by a step in the sign of the offset's first
    component instead (a function a linear regression of the window fits poorly)."""
    rng = np.random.default_rng(seed)
    level, freq = rng.normal(0, 1, 4), rng.uniform(0.5, 1.5, 4)
    q0, q1, gain = rng.normal(0, 0.3, 3), rng.normal(0, 0.8, 3), rng.normal(0, 0.25, (3, 4))
    demos = []
    for i in range(n_demos):
        duration = rng.uniform(1.8, 2.4)
        t = np.arange(0.0, duration + 1e-9, 1.0 / 25.0)
        z = t / t[-1]
        h = rng.normal(0, 1, 4)
        wig = sum(
            rng.normal(0, 0.3, 4) * np.sin((j + 1) * np.pi * z[:, None] + rng.uniform(0, 6, 4))
            for j in range(4)
        )
        human = level + h + np.sin(2 * np.pi * freq * z[:, None]) + wig + rng.normal(0, 0.05, (t.size, 4))
        smooth = z**3 * (10 - 15 * z + 6 * z**2)
        robot_wig = sum(rng.normal(0, 0.3, 3) * np.sin((j + 1) * np.pi * z[:, None]) for j in range(4))
        shift = gain[:, 0] * 4.0 * np.sign(h[0]) if step else gain @ h
        q = q0 + smooth[:, None] * (q1 + shift) + robot_wig + rng.normal(0, 0.002, (t.size, 3))
        names = {"a": tuple(f"a{j}" for j in range(4)), ROBOT: ("j0", "j1", "j2")}
        demos.append(
            Demo(task="task0", name=f"d{i}", source=f"informative({seed})/{i}", t=t,
                 groups={"a": human, ROBOT: q}, channel_names=names, missing={})
        )  # fmt: skip
    return Dataset(f"informative({seed})", {"task0": demos})


@pytest.fixture(scope="module")
def fused():
    """A model fitted on 15 demos of :func:`informative_dataset` (with the hand-over regression, which
    its cross-validation chose), and the 8 test demos."""
    ds = informative_dataset()
    train = Dataset(ds.root, {"task0": ds.demos["task0"][:15]})
    model = IProMP(["a"], n_basis=10, n_alpha=40).fit(train, fk=fk)
    return model, train, ds.demos["task0"][15:]


def _handover_error(model: IProMP, test: list[Demo], ratio: float) -> float:
    """Mean gripper position error at the hand-over over the test demos."""
    errs = [
        np.linalg.norm(fk(model.predict(d.head(ratio, ["a"])).q_mean[-1]) - fk(d.groups[ROBOT][-1]))
        for d in test
    ]
    return float(np.mean(errs))


def _unfused(model: IProMP) -> IProMP:
    """The same fitted model without its hand-over regression."""
    off = IProMP(**model.get_params())
    off._set_fitted(replace(model.fitted_, handover=None, handover_cv_scores={}))
    return off


def test_fit_ridge_leave_one_out_is_exact() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(14, 4)) * [1.0, 10.0, 0.1, 3.0]
    y = x @ rng.normal(size=(4, 2)) + rng.normal(0, 0.5, (14, 2))
    fit = fit_ridge(x, y)
    assert fit.coef.shape == (2, 4) and fit.intercept.shape == (2,)
    for i in range(x.shape[0]):  # the residual of row i equals that of a refit without it
        keep = np.arange(x.shape[0]) != i
        # the exact formula keeps the full fit's standardisation: refit on that scaling
        full_mean, full_scale = x.mean(0), np.where(x.std(0) > 1e-12, x.std(0), 1.0)
        z = (x[keep] - full_mean) / full_scale
        zc, yc = z - z.mean(0), y[keep] - y[keep].mean(0)
        w = np.linalg.solve(zc.T @ zc + fit.penalty * np.eye(4), zc.T @ yc)
        pred = ((x[i] - full_mean) / full_scale - z.mean(0)) @ w + y[keep].mean(0)
        assert np.allclose(fit.residuals[i], y[i] - pred, atol=1e-9)


def test_readouts_are_the_jacobian_of_the_kinematics() -> None:
    q = np.array([[0.3, -0.2, 0.7], [1.0, 0.5, -0.4]])
    a = readouts(q, fk)
    assert a.shape == (2, 3, 3)
    step = 1e-7
    for k in range(2):
        num = np.stack([(fk(q[k] + step * e) - fk(q[k] - step * e))[0] / (2 * step) for e in np.eye(3)], 1)
        assert np.allclose(a[k], num, atol=1e-6)
    assert np.array_equal(readouts(q, None), np.repeat(np.eye(3)[None], 2, axis=0))


def test_trust_is_chosen_by_cross_validation(fused) -> None:
    model, _, _ = fused
    scores = model.handover_cv_scores_
    assert set(scores) == {np.inf, *TRUST_GRID}
    best = min(scores, key=scores.get)
    assert np.isfinite(best) and model.handover_ is not None and model.handover_.trust == best
    assert model.handover_.ratios.tolist() == list(RATIOS)
    assert model.handover_.readout.shape == (1, 3, 3)  # the gripper position's Jacobian


def test_fused_prediction_is_closer_where_the_regression_is_informative(fused) -> None:
    model, _, test = fused
    off = _unfused(model)
    for ratio in (0.3, 0.5):
        assert _handover_error(model, test, ratio) < 0.8 * _handover_error(off, test, ratio)


def test_off_reproduces_the_unfused_prediction_exactly(fused) -> None:
    model, train, test = fused
    plain = IProMP(**{**model.get_params(), "handover": False}).fit(train, fk=fk)
    assert plain.handover_ is None and plain.handover_cv_scores_ == {}
    obs = test[0].head(0.4, ["a"])
    a, b = plain.predict(obs), _unfused(model).predict(obs)
    for name in ("log_posterior", "alpha", "q_mean", "q_cov"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    # a regression the cross-validation turned off is no regression
    choice = IProMP(**model.get_params())
    choice._set_fitted(replace(model.fitted_, handover=None))
    assert np.array_equal(choice.predict(obs).q_mean, b.q_mean)


def test_fusion_keeps_a_covariance_and_only_reduces_it(fused) -> None:
    model, _, test = fused
    obs = test[1].head(0.3, ["a"])
    a, b = model.predict(obs), _unfused(model).predict(obs)
    assert np.array_equal(a.log_posterior, b.log_posterior) and np.array_equal(a.alpha, b.alpha)
    assert not np.allclose(a.q_mean[-1], b.q_mean[-1])
    for ca, cb in zip(a.q_cov, b.q_cov, strict=True):
        assert np.allclose(ca, ca.T) and np.linalg.eigvalsh(ca).min() > 0.0
        assert np.linalg.eigvalsh(cb - ca).min() > -1e-12  # conditioning never adds uncertainty
    assert np.trace(a.q_cov[-1]) < np.trace(b.q_cov[-1])


def test_round_trip_with_the_regression(tmp_path: Path, fused) -> None:
    model, _, test = fused
    path = tmp_path / "m.npz"
    model.save(path)
    loaded = IProMP.load(path)
    assert loaded.handover_cv_scores_ == model.handover_cv_scores_
    assert loaded.handover_.trust == model.handover_.trust
    obs = test[2].head(0.5, ["a"])
    a, b = model.predict(obs), loaded.predict(obs)
    for name in ("log_posterior", "alpha", "q_mean", "q_cov"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    header = json.loads(str(np.load(path)["header"][()]))
    assert header["format_version"] == FORMAT_VERSION and header["handover"]["trust"] == model.handover_.trust
    assert header["handover"]["neighbours"] is None and "handover_kind" not in np.load(path).files


def test_version_2_file_loads_without_the_regression(tmp_path: Path, fused) -> None:
    model, _, test = fused
    model.save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as npz:
        new = ("head_kind", "head_generative")
        arrays = {k: npz[k] for k in npz.files if not k.startswith("handover_") and k not in new}
    header = json.loads(str(arrays["header"][()]))
    for key in ("handover", "handover_cv_scores"):
        header.pop(key)
    header["params"].pop("handover")
    header["format_version"] = 2
    arrays["header"] = np.array(json.dumps(header))
    np.savez(tmp_path / "v2.npz", **arrays)
    old = IProMP.load(tmp_path / "v2.npz")
    assert old.handover_ is None and old.get_params()["handover"] is False
    obs = test[1].head(0.4, ["a"])
    assert (
        np.array_equal(old.predict(obs).q_mean, _unfused(model).predict(obs).q_mean)
        or model.head_ is not None
    )


def test_a_file_with_a_broken_regression_is_refused_in_one_line(tmp_path: Path, fused) -> None:
    model, _, _ = fused
    model.save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    cov = arrays["handover_residual_cov"].copy()
    cov[0] = -np.eye(cov.shape[1])
    arrays["handover_residual_cov"] = cov
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ModelFileError) as info:
        IProMP.load(tmp_path / "bad.npz")
    assert "\n" not in str(info.value) and "handover" in str(info.value)
    assert zipfile.is_zipfile(tmp_path / "bad.npz")


@pytest.fixture(scope="module")
def stepped():
    """A model fitted on 15 demos of :func:`informative_dataset` with a step (its cross-validation
    chose the k-nearest-neighbour estimates), and the 8 test demos."""
    ds = informative_dataset(step=True)
    train = Dataset(ds.root, {"task0": ds.demos["task0"][:15]})
    model = IProMP(["a"], n_basis=10, n_alpha=40).fit(train, fk=fk)
    return model, train, ds.demos["task0"][15:]


def test_fit_knn_leave_one_out_is_exact_and_beats_ridge_on_a_step() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(16, 2)) * [1.0, 20.0]
    y = np.stack([np.sign(x[:, 0]), 2.0 * np.sign(x[:, 0])], 1) + rng.normal(0, 0.05, (16, 2))
    fit = fit_knn(x, y)
    assert 1 <= fit.k <= 10 and fit.residuals.shape == (16, 2)
    for i in range(16):  # the residual of row i is the prediction from the other rows
        keep = np.arange(16) != i
        d = np.linalg.norm((x[keep] - fit.mean) / fit.scale - (x[i] - fit.mean) / fit.scale, axis=1)
        assert np.allclose(fit.residuals[i], y[i] - knn_predict(d, y[keep], fit.k, fit.distance))
    assert np.sum(fit.residuals**2) < np.sum(fit_ridge(x, y).residuals ** 2)
    assert np.allclose(fit.predict(x[3]), y[3]) or fit.k > 1  # an exact match takes all the weight
    assert np.array_equal(knn_predict(np.array([0.0, 1.0, 2.0]), np.eye(3), 3, True), [1.0, 0.0, 0.0])
    assert fit_knn(x[:1], y[:1]) is None


def test_stored_neighbours_predict_as_the_fits() -> None:
    rng = np.random.default_rng(2)
    x = [rng.normal(size=(n, 4)) for n in (9, 12)]
    y = [rng.normal(size=(n, 3)) for n in (9, 12)]
    fits = [[fit_ridge(x[0], y[0]), fit_ridge(x[1], y[1])], [fit_knn(x[0], y[0]), fit_knn(x[1], y[1])]]
    arrays = neighbour_arrays(fits, 3, 4)
    assert arrays["kind"].tolist() == [0.0, 1.0] and arrays["neighbour_x"].shape == (2, 2, 12, 4)
    zero = np.zeros((2, 2, 3, 4))
    coef = np.stack([np.stack([fits[0][0].coef, fits[0][1].coef]), zero[1]])
    intercept = np.stack([np.stack([fits[0][0].intercept, fits[0][1].intercept]), np.zeros((2, 3))])
    ho = HandoverRegression(
        ratios=np.array([0.2, 0.4]), dims=np.array([0, 1]), readout=np.repeat(np.eye(3)[None], 2, 0),
        coef=coef, intercept=intercept, residual_cov=np.repeat(np.eye(3)[None], 2, 0), trust=1.0, **arrays,
    )  # fmt: skip
    window = rng.normal(size=(3, 2))
    feats = window[1:].reshape(-1)
    for task in (0, 1):
        for frac, fit in ((0.2, fits[0][task]), (0.4, fits[1][task])):
            _, pred, _ = ho.observation(task, WindowSummary(window), frac)
            assert np.allclose(pred, fit.predict(feats))
        _, mid, _ = ho.observation(task, WindowSummary(window), 0.3)
        assert np.allclose(mid, 0.5 * (fits[0][task].predict(feats) + fits[1][task].predict(feats)))


def test_neighbours_are_chosen_on_a_step_and_ridge_on_a_linear_coupling(fused, stepped) -> None:
    assert fused[0].handover_.kind is None  # linear: the ridge regression at every fraction
    ho = stepped[0].handover_
    assert ho is not None and ho.kind is not None and ho.kind.sum() >= 1
    assert np.all(ho.neighbour_count[ho.kind == 1] == 15)


def test_round_trip_with_neighbours_and_version_3_files(tmp_path: Path, stepped) -> None:
    model, _, test = stepped
    path = tmp_path / "m.npz"
    model.save(path)
    loaded = IProMP.load(path)
    obs = test[2].head(0.5, ["a"])
    a, b = model.predict(obs), loaded.predict(obs)
    for name in ("log_posterior", "alpha", "q_mean", "q_cov"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    header = json.loads(str(arrays["header"][()]))
    assert header["format_version"] == FORMAT_VERSION and header["handover"]["neighbours"] == 15
    # a version-3 file (no neighbours) loads as an all-ridge regression
    for key in [k for k in arrays if k == "handover_kind" or k.startswith("handover_neighbour_")]:
        arrays.pop(key)
    header["handover"].pop("neighbours")
    header["format_version"] = 3
    arrays["header"] = np.array(json.dumps(header))
    np.savez(tmp_path / "v3.npz", **arrays)
    old = IProMP.load(tmp_path / "v3.npz")
    assert old.handover_.kind is None
    assert np.isfinite(old.predict(obs).q_mean).all()
    # broken neighbour counts are refused in one line
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["handover_neighbour_count"] = arrays["handover_neighbour_count"] + 100.0
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ModelFileError) as info:
        IProMP.load(tmp_path / "bad.npz")
    assert "\n" not in str(info.value) and "neighbour_count" in str(info.value)
