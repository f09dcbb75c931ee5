"""IProMP: fit / predict / recognise / stream, conditioning quality and input errors;
observation and training channels matched by name."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.data import Dataset, Demo
from ipromp_pin.exceptions import DataError, ModelError, NotFittedError, ObservationError
from ipromp_pin.promp import NOISE_GRID, IProMP, Prediction
from ipromp_pin.readers.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def fitted() -> tuple[IProMP, dict[str, list[Demo]]]:
    train, test = split(random_dataset(11, n_demos=12), 8)
    return IProMP(["a", "b"], n_basis=10, n_alpha=50).fit(train), test


def test_prediction_fields(fitted) -> None:
    model, test = fitted
    obs = test["task2"][0].head(0.2, model.observe)
    p = model.predict(obs)
    assert isinstance(p, Prediction)
    assert p.tasks == model.tasks_ and p.task == "task2"
    assert np.isclose(p.posterior.sum(), 1.0) and np.allclose(np.exp(p.log_posterior), p.posterior)
    assert p.alpha.shape == (3,) and p.phase_grid.shape == p.phase_log_post.shape
    assert p.phase_grid.shape[0] == 3 and p.phase_grid.shape[1] >= 50
    assert p.t[0] == 0.0 and np.isclose(p.t[-1], p.duration_s) and p.t.size == model.n_points
    assert np.isclose(p.duration_s, p.alpha[2] * model.duration_nominal_s_)
    assert p.q_mean.shape == p.q_prior_mean.shape == (model.n_points, 3)
    assert p.q_cov.shape == (model.n_points, 3, 3)
    assert np.allclose(p.q_cov, np.swapaxes(p.q_cov, 1, 2))
    assert np.linalg.eigvalsh(p.q_cov).min() > 0
    assert p.joint_names == ("j0", "j1", "j2")
    assert set(p.human_mean) == {"a", "b"} and p.human_mean["b"].shape == (model.n_points, 3)
    assert p.observed_until_s == obs.t[-1]


def test_samples_match_mean_and_covariance(fitted) -> None:
    model, test = fitted
    p = model.predict(test["task0"][1].head(0.3, model.observe))
    q = p.sample_q(4000, rng=0)
    assert q.shape == (4000, model.n_points, 3)
    sd = np.sqrt(np.diagonal(p.q_cov, axis1=1, axis2=2))
    assert np.all(np.abs(q.mean(axis=0) - p.q_mean) < 0.1 * sd + 1e-9)
    i = model.n_points // 2
    emp = np.cov(q[:, i].T)
    assert np.allclose(emp, p.q_cov[i], atol=0.1 * p.q_cov[i].diagonal().max())


def test_recognition_accuracy(fitted) -> None:
    model, test = fitted
    hits = [model.recognise(d.head(0.2, model.observe)).task == t for t, ds in test.items() for d in ds]
    assert np.mean(hits) >= 0.9


def test_conditioning_beats_the_prior_when_robot_follows_the_human() -> None:
    # the robot's hand-over configuration follows the human's amplitude: conditioning must use it
    train, test = split(random_dataset(12, n_demos=30, coupling=1.0), 20)
    model = IProMP(["a", "b"], n_basis=10, n_alpha=50).fit(train)
    cond, prior = [], []
    for demos in test.values():
        for d in demos:
            p = model.predict(d.head(0.3, model.observe))
            z = p.t / p.duration_s
            truth = np.stack([np.interp(z, d.t / d.t[-1], d.groups["robot"][:, j]) for j in range(3)], axis=1)
            cond.append(np.sqrt(np.mean((p.q_mean - truth) ** 2)))
            prior.append(np.sqrt(np.mean((p.q_prior_mean - truth) ** 2)))
    assert np.mean(cond) < 0.8 * np.mean(prior)


def test_stream_equals_one_shot_with_missing_samples() -> None:
    train, test = split(random_dataset(13, missing_group="a"), 6)
    model = IProMP(["a", "b"], n_basis=8, n_alpha=50, noise=1.0).fit(train)
    demo = test["task1"][0].head(0.4, model.observe)
    stream = model.stream()
    assert stream.update(demo.t[0], {g: demo.groups[g][0] for g in model.observe}) is None
    for j in range(1, demo.n_samples):
        sample = {g: demo.groups[g][j] for g in model.observe}
        if demo.missing["a"][j]:
            sample["a"] = None
        rec = stream.update(demo.t[j], sample)
    one = model.recognise(demo)
    assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
    assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)
    finite = np.isfinite(one.phase_log_post)
    assert np.array_equal(finite, np.isfinite(rec.phase_log_post))
    assert np.allclose(rec.phase_log_post[finite], one.phase_log_post[finite], rtol=1e-9, atol=1e-8)
    pred = stream.prediction()
    assert np.allclose(pred.q_mean, model.predict(demo).q_mean, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("noise", [1.0, 0.03])
def test_incremental_stream_equals_one_shot_at_every_sample(noise: float) -> None:
    # no missing samples: the incremental (Sherman-Morrison) path, rebuilt as the window grows
    train, test = split(random_dataset(14, n_demos=8), 6)
    model = IProMP(["a", "b"], n_basis=16, n_alpha=50, noise=noise).fit(train)
    demo = test["task0"][0].head(0.6, model.observe)
    stream = model.stream()
    kes = set()
    for j in range(demo.n_samples):
        rec = stream.update(demo.t[j], {g: demo.groups[g][j] for g in model.observe})
        if j == 0:
            continue
        kes.add(stream.incremental.ke)
        one = model.recognise(demo.slice(j + 1))
        finite = np.isfinite(one.phase_log_post)
        assert np.array_equal(finite, np.isfinite(rec.phase_log_post))
        assert np.allclose(rec.phase_log_post[finite], one.phase_log_post[finite], rtol=1e-9, atol=1e-8)
        assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
        assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)
    assert len(kes) >= 2  # the incremental terms were rebuilt at least once
    pred = stream.prediction()
    assert np.allclose(pred.q_mean, model.predict(demo).q_mean, rtol=1e-12, atol=1e-12)


def test_coupling_keeps_every_group_that_informs_the_robot(fitted) -> None:
    # in random_dataset the robot follows the amplitude shared by both human groups
    model, _ = fitted
    assert model.coupling == "auto" and model.coupled_groups_ == ["a", "b"]
    scores = model.coupling_cv_scores_
    assert set(scores) == {"a+b", "a", "b"} and scores["a+b"] < min(scores["a"], scores["b"])
    m = model.models_["task0"]
    assert np.all(m.shrinkage == m.shrinkage[0]) and m.rank <= 7  # one block: rank <= N - 1


def test_noise_is_chosen_by_cross_validation(fitted) -> None:
    model, _ = fitted
    assert model.noise_ratio_ in NOISE_GRID
    assert set(model.cv_scores_) == set(NOISE_GRID)
    assert model.cv_scores_[model.noise_ratio_] == max(model.cv_scores_.values())
    for var in model.noise_var_.values():
        assert var.shape == (5,) and np.all(var > 0)


def test_distribution_and_training_trajectories(fitted) -> None:
    model, _ = fitted
    z = np.linspace(0, 1, 20)
    mean, std, labels = model.distribution("task0", z)
    assert mean.shape == std.shape == (20, 8) and labels[0] == "a/a0" and labels[-1] == "robot/j2"
    trajs = model.train_trajectories("task0", z)
    assert trajs.shape == (8, 20, 8)
    assert np.allclose(trajs.mean(axis=0), mean, atol=1e-9)
    assert np.all(std > 0)
    with pytest.raises(ModelError, match="unknown task"):
        model.distribution("nope", z)


# ------------------------------------------------------------------ bad input


def test_task_with_one_demo_is_rejected() -> None:
    ds = random_dataset(14, n_demos=2)
    ds.demos["task0"] = ds.demos["task0"][:1]
    with pytest.raises(DataError, match="task0.*at least 2"):
        IProMP(["a", "b"], n_basis=6, noise=1.0).fit(ds)


def test_training_demo_without_observed_group_is_rejected() -> None:
    ds = random_dataset(15, n_demos=3)
    with pytest.raises(DataError, match="'c'"):
        IProMP(["a", "c"], n_basis=6, noise=1.0).fit(ds)


def test_predict_before_fit() -> None:
    demo = random_dataset(16, n_demos=2).demos["task0"][0]
    with pytest.raises(NotFittedError):
        IProMP(["a", "b"]).predict(demo)
    with pytest.raises(NotFittedError):
        IProMP(["a", "b"]).stream()


@pytest.mark.parametrize(
    "kwargs", [{"noise": -1.0}, {"noise": "tight"}, {"n_alpha": 2}, {"observe": ["robot"]}]
)
def test_bad_parameters_are_refused_by_fit(kwargs: dict) -> None:
    # __init__ only stores the parameters (scikit-learn convention); fit validates them first
    model = IProMP(**{"observe": ["a"], **kwargs})
    assert all(model.get_params()[k] is v for k, v in kwargs.items())
    with pytest.raises((ModelError, DataError)):
        model.fit(random_dataset(11, n_demos=3))


def test_observation_errors(fitted) -> None:
    model, test = fitted
    demo = test["task0"][0]
    with pytest.raises(ObservationError, match="field 'b'.*missing"):
        model.predict(demo.head(0.2, ["a"]))
    wrong = Demo(
        "x",
        "w",
        "wrong.npz",
        demo.t,
        {"a": demo.groups["a"], "b": demo.groups["b"][:, :2]},
        {"a": demo.channel_names["a"], "b": ("b0", "b1")},
    )
    with pytest.raises(ObservationError, match="field 'b'.*2 channels.*expects 3"):
        model.predict(wrong)
    t_long = np.arange(0, 40.0, 0.04)
    long = Demo(
        "x",
        "l",
        "long.npz",
        t_long,
        {"a": np.zeros((t_long.size, 2)), "b": np.zeros((t_long.size, 3))},
        {"a": demo.channel_names["a"], "b": demo.channel_names["b"]},
    )
    # longer than any learned motion: no task explains it, which is an answer (unknown), not an error
    for rec in (model.recognise(long), model.predict(long)):
        assert not rec.known and rec.novelty_p_value == 0.0
        assert rec.unknown_reason is not None and "impossible under every task" in rec.unknown_reason
        assert rec.task in model.tasks_
    assert np.all(np.isfinite(model.predict(long).q_mean))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_predict_rejects_non_finite_values_not_flagged_missing(fitted, bad: float) -> None:
    # Demo rejects such values when built; one changed afterwards reaches predict, which scales and
    # checks the values in one kernel: a NaN or inf sample not flagged as missing names its group
    model, test = fitted
    obs = test["task0"][0].head(0.2, model.observe)
    groups = {g: v.copy() for g, v in obs.groups.items()}
    broken = Demo(obs.task, obs.name, "bad.csv", obs.t, groups, obs.channel_names)
    broken.groups["b"][3, 1] = bad
    for call in (model.predict, model.recognise):
        with pytest.raises(ObservationError, match="bad.csv.*field 'b'.*NaN or inf"):
            call(broken)
    assert model.predict(obs).q_mean.shape == (model.n_points, 3)  # the clean observation still works


def test_stream_errors(fitted) -> None:
    model, test = fitted
    demo = test["task0"][0]
    stream = model.stream()
    with pytest.raises(ObservationError, match="stream"):
        stream.prediction()
    stream.update(0.0, {"a": demo.groups["a"][0], "b": demo.groups["b"][0]})
    with pytest.raises(ObservationError, match="field 'b'.*NaN"):
        stream.update(0.04, {"a": demo.groups["a"][1], "b": np.array([np.nan, 0.0, 0.0])})
    with pytest.raises(ObservationError, match="field 'a'.*expects 2"):
        stream.update(0.04, {"a": np.zeros(3), "b": demo.groups["b"][1]})
    with pytest.raises(ObservationError, match="not after"):
        stream.update(0.0, {"a": demo.groups["a"][1], "b": demo.groups["b"][1]})
    with pytest.raises(ObservationError, match="'c'"):
        stream.update(0.04, {"a": demo.groups["a"][1], "c": np.zeros(1)})


@pytest.mark.parametrize("first_missing", [False, True])
def test_incremental_stream_with_gaps_equals_one_shot_at_every_sample(first_missing: bool) -> None:
    # a group missing in some samples (the first one too) splits the stream's presence pattern in
    # two parts with their own X: the terms stay incremental (per part Sherman-Morrison and rank-D
    # updates) and equal the one-shot recognition of the same samples, gaps included
    train, test = split(random_dataset(14, n_demos=8), 6)
    model = IProMP(["a", "b"], n_basis=16, n_alpha=50, noise=1.0).fit(train)
    demo = test["task0"][0].head(0.6, model.observe)
    gaps = {0, 5, 9, 10} if first_missing else {4, 9, 10}
    stream = model.stream()
    kes = set()
    for j in range(demo.n_samples):
        sample = {g: demo.groups[g][j] for g in model.observe}
        if j in gaps:
            sample["a"] = None
        if j == 12:
            sample = {}  # every group missing at once
        rec = stream.update(demo.t[j], sample)
        if j == 0:
            continue
        assert stream.incremental is not None and stream.incremental.ke >= 0
        kes.add(stream.incremental.ke)
        one = model.recognise(stream.observation())
        finite = np.isfinite(one.phase_log_post)
        assert np.array_equal(finite, np.isfinite(rec.phase_log_post))
        assert np.allclose(rec.phase_log_post[finite], one.phase_log_post[finite], rtol=1e-9, atol=1e-8)
        assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
        assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)
    assert len(stream.incremental.parts) == 2
    assert len(kes) >= 2  # rebuilt from the statistics of both parts as the window grew


@pytest.mark.parametrize("with_gap", [False, True])
def test_stream_rejected_sample_leaves_the_estimate_unchanged(with_gap: bool) -> None:
    # a sample with an inf is refused (naming its group) before it touches the running statistics,
    # on the one-call path (every group present) and on the general path (a group missing before);
    # the statistics feed the rebuilds of the incremental terms as the window grows
    train, test = split(random_dataset(14, n_demos=8), 6)
    model = IProMP(["a", "b"], n_basis=16, n_alpha=50, noise=1.0).fit(train)
    demo = test["task0"][0].head(0.6, model.observe)
    stream = model.stream()
    kes = set()
    for j in range(demo.n_samples):
        sample = {g: demo.groups[g][j] for g in model.observe}
        if with_gap and j == 2:
            sample["a"] = None
        if j == 3:
            bad = dict(sample, b=np.array([0.0, np.inf, 0.0]))
            with pytest.raises(ObservationError, match="field 'b'.*NaN or inf"):
                stream.update(demo.t[j], bad)
            assert stream.n_samples == j
        rec = stream.update(demo.t[j], sample)
        if stream.incremental is not None:
            kes.add(stream.incremental.ke)
    assert with_gap or len(kes) >= 2  # rebuilt from the statistics after the refused sample
    one = model.recognise(stream.observation())
    assert stream.n_samples == demo.n_samples
    assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
    assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)


# ------------------------------------------------------------------ coupling


def _shuffle_group(ds: Dataset, group: str, seed: int) -> Dataset:
    """Each demo gets ``group`` of another demo of its task (time-normalised): the group keeps its
    task-specific shape (useful for recognition) but says nothing about this demo's robot motion."""
    rng = np.random.default_rng(seed)
    out = {}
    for task, demos in ds.demos.items():
        new = []
        for d, j in zip(demos, rng.permutation(len(demos)), strict=True):
            src = demos[j]
            z, zs = d.t / d.t[-1], src.t / src.t[-1]
            v = np.stack([np.interp(z, zs, c) for c in src.groups[group].T], axis=1)
            new.append(Demo(d.task, d.name, d.source, d.t, {**d.groups, group: v}, d.channel_names))
        out[task] = new
    return Dataset(ds.root, out)


def _rmse(p: Prediction, d: Demo, q: np.ndarray) -> float:
    z = p.t / p.duration_s
    truth = np.stack([np.interp(z, d.t / d.t[-1], c) for c in d.groups["robot"].T], axis=1)
    return float(np.sqrt(np.mean((q - truth) ** 2)))


@pytest.fixture(scope="module")
def shuffled() -> tuple[Dataset, dict[str, list[Demo]]]:
    return split(_shuffle_group(random_dataset(31, n_demos=26), "b", 31), 18)


def test_coupling_leaves_out_a_group_unrelated_to_the_robot(shuffled) -> None:
    train, test = shuffled
    auto = IProMP(["a", "b"], n_basis=10, n_alpha=50).fit(train)
    full = IProMP(["a", "b"], n_basis=10, n_alpha=50, coupling="all").fit(train)
    assert auto.coupled_groups_ == ["a"] and full.coupled_groups_ == ["a", "b"]
    scores = auto.coupling_cv_scores_
    assert set(scores) == {"a+b", "a", "b"} and min(scores, key=scores.get) == "a"
    assert full.coupling_cv_scores_ == {}
    # b is independent of a and of the robot, and has its own shrinkage intensity
    m = auto.models_["task0"]
    b_dims, robot_dims = np.arange(2, 5), np.arange(5, 8)
    cov = m.covariance().reshape(8, 10, 8, 10)
    assert np.all(cov[np.ix_(b_dims, range(10), np.r_[0, 1, robot_dims], range(10))] == 0.0)
    assert np.all(m.shrinkage[b_dims] == m.shrinkage[2]) and m.shrinkage[2] != m.shrinkage[0]
    assert np.linalg.eigvalsh(m.covariance()).min() > 0.0
    err_auto, err_full, err_prior, hits = [], [], [], []
    for demos in test.values():
        for d in demos:
            obs = d.head(0.3, auto.observe)
            p, pf = auto.predict(obs), full.predict(obs)
            hits.append(p.task == d.task)
            err_auto.append(_rmse(p, d, p.q_mean))
            err_full.append(_rmse(pf, d, pf.q_mean))
            err_prior.append(_rmse(p, d, p.q_prior_mean))
    assert np.mean(hits) >= 0.9
    assert np.mean(err_auto) < np.mean(err_full) and np.mean(err_auto) < 0.5 * np.mean(err_prior)


def test_explicit_coupling(shuffled) -> None:
    train, test = shuffled
    none = IProMP(["a", "b"], n_basis=10, n_alpha=50, noise=1.0, coupling=[]).fit(train)
    assert none.coupled_groups_ == [] and none.coupling_cv_scores_ == {}
    p = none.predict(test["task1"][0].head(0.3, none.observe))
    assert np.allclose(p.q_mean, p.q_prior_mean, atol=1e-12)  # the robot is independent of the human


@pytest.mark.parametrize("coupling", ["some", ["c"], ["a", "a"], ["robot"]])
def test_bad_coupling(coupling) -> None:
    with pytest.raises(ModelError, match="coupling"):
        IProMP(["a", "b"], coupling=coupling).fit(random_dataset(11, n_demos=3))


def test_coupling_survives_save_and_load(tmp_path, shuffled) -> None:
    train, test = shuffled
    model = IProMP(["a", "b"], n_basis=10, n_alpha=50, noise=1.0).fit(train)
    path = tmp_path / "m.npz"
    model.save(path)
    loaded = IProMP.load(path)
    assert loaded.coupling == "auto" and loaded.coupled_groups_ == model.coupled_groups_ == ["a"]
    assert loaded.coupling_cv_scores_ == model.coupling_cv_scores_
    for t in model.tasks_:
        assert np.array_equal(loaded.models_[t].shrinkage, model.models_[t].shrinkage)
    obs = test["task2"][0].head(0.3, model.observe)
    assert np.array_equal(loaded.predict(obs).q_mean, model.predict(obs).q_mean)
    # a file written before the coupling existed loads as a fully coupled model
    full = IProMP(["a", "b"], n_basis=10, n_alpha=50, noise=1.0, coupling="all").fit(train)
    full.save(path)
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files if not k.endswith("_shrinkage")}
    header = json.loads(str(arrays["header"][()]))
    for key in ("coupled_groups", "coupling_cv_scores"):
        del header[key]
    del header["params"]["coupling"]
    arrays["header"] = np.array(json.dumps(header))
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    loaded = IProMP.load(old)
    assert loaded.coupling == "all" and loaded.coupled_groups_ == ["a", "b"]
    assert np.all(loaded.models_["task0"].shrinkage == full.models_["task0"].shrinkage[0])
    assert np.array_equal(loaded.predict(obs).q_mean, full.predict(obs).q_mean)


def test_stream_equals_one_shot_with_two_blocks(shuffled) -> None:
    train, test = shuffled
    model = IProMP(["a", "b"], n_basis=10, n_alpha=50, noise=1.0, coupling=["a"]).fit(train)
    assert model.models_["task0"].rank > 17  # two blocks of rank N - 1 = 17 each
    demo = test["task1"][1].head(0.4, model.observe)
    stream = model.stream()
    for j in range(demo.n_samples):
        rec = stream.update(demo.t[j], {g: demo.groups[g][j] for g in model.observe})
    one = model.predict(demo)
    assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
    assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)
    assert np.allclose(stream.prediction().q_mean, one.q_mean, rtol=1e-12, atol=1e-12)


def test_distribution_band_of_a_log_scaled_channel_is_in_original_units() -> None:
    from ipromp_pin.readers.synthetic import make_synthetic_dataset

    ds = make_synthetic_dataset(n_tasks=2, n_demos=8, seed=4)
    model = IProMP(["orientation", "emg"], n_basis=8, noise=10.0).fit(ds)
    z = np.linspace(0.05, 0.95, 12)
    centre, spread, labels = model.distribution("rod", z)
    mid, lower, upper, band_labels = model.distribution_band("rod", z, 2.0)
    assert band_labels == labels and np.allclose(mid, centre)
    emg = np.array([label.startswith("emg/") for label in labels])
    assert emg.any() and (~emg).any()
    scaler = model.scaler_
    c = scaler.log_shift[emg]
    # log-scaled: the quantiles exp(mu +- 2 sigma) - c around the median exp(mu) - c (sigma in log units)
    mu = np.log(centre[:, emg] + c)
    assert np.allclose(lower[:, emg], np.exp(mu - 2 * spread[:, emg]) - c)
    assert np.allclose(upper[:, emg], np.exp(mu + 2 * spread[:, emg]) - c)
    assert np.all(upper[:, emg] - centre[:, emg] > centre[:, emg] - lower[:, emg])  # asymmetric
    # linear channels: mean +- 2 std
    assert np.allclose(lower[:, ~emg], centre[:, ~emg] - 2 * spread[:, ~emg])
    # about 95 % of the training demos' values lie in the band
    demos = model.train_trajectories("rod", z)
    inside = (demos >= lower) & (demos <= upper)
    assert inside[..., emg].mean() > 0.85


def test_observation_channels_are_matched_by_name():
    ds = random_dataset(3, n_demos=5)
    model = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    obs = ds.demos["task1"][0].head(0.3, ["a", "b"])
    perm = [2, 0, 1]
    shuffled = dataclasses.replace(
        obs,
        groups={**obs.groups, "b": obs.groups["b"][:, perm]},
        channel_names={**obs.channel_names, "b": tuple(obs.channel_names["b"][i] for i in perm)},
    )
    a, b = model.predict(obs), model.predict(shuffled)
    assert np.array_equal(a.q_mean, b.q_mean) and np.array_equal(a.log_posterior, b.log_posterior)
    renamed = dataclasses.replace(obs, channel_names={**obs.channel_names, "b": ("x", "y", "z")})
    with pytest.raises(ObservationError, match="not the expected"):
        model.predict(renamed)


def test_training_channels_are_matched_by_name():
    ds = random_dataset(4, n_tasks=2, n_demos=4)
    reference = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    demo = ds.demos["task1"][2]
    perm = [1, 0]
    ds.demos["task1"][2] = dataclasses.replace(
        demo,
        groups={**demo.groups, "a": demo.groups["a"][:, perm]},
        channel_names={**demo.channel_names, "a": tuple(demo.channel_names["a"][i] for i in perm)},
    )
    model = IProMP(["a", "b"], n_basis=9, noise=10.0).fit(ds)
    assert np.array_equal(model.scaler_.scale, reference.scaler_.scale)
    assert np.array_equal(model.models_["task1"].mean, reference.models_["task1"].mean)


def test_stream_with_a_lost_group_in_a_two_block_model() -> None:
    # orientation and EMG in two latent blocks that share their lanes (the default coupling on the
    # synthetic hand-overs): a sample without one of them makes a part with none of the other
    # block's dims, which the stream takes incrementally (it raised a reshape error before)
    ds = make_synthetic_dataset(n_tasks=2, n_demos=9, seed=0)
    train = type(ds)(ds.root, {t: d[:8] for t, d in ds.demos.items()})
    model = IProMP(["orientation", "emg"], noise=10.0, head=False, handover=False).fit(train)
    stream = model.stream()
    demo = ds.demos[ds.tasks[0]][8].head(0.4, model.observe)
    n_checked = 0
    for j in range(demo.n_samples):
        sample = {g: demo.groups[g][j] for g in model.observe}
        if j in (6, 7, 8):
            sample["emg"] = None
        if j == 11:
            sample["orientation"] = None
        rec = stream.update(demo.t[j], sample)
        if j < 2:
            continue
        one = model.recognise(stream.observation())
        assert np.allclose(rec.log_posterior, one.log_posterior, rtol=1e-9, atol=1e-9)
        assert np.allclose(rec.alpha, one.alpha, rtol=1e-9)
        n_checked += 1
    engine = stream.incremental.engine
    assert any(len(group) == 2 for group in engine.lane_groups)  # two blocks in one lane group
    assert len(stream.incremental.parts) == 2 and n_checked > 10  # orientation, EMG
    pred = stream.predict()
    ref = model.predict(stream.observation())
    assert pred.task == ref.task
    assert np.allclose(pred.q_mean, ref.q_mean, rtol=1e-8, atol=1e-10)
