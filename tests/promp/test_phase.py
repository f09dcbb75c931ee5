"""Phase estimation: exact candidate likelihood, refinement, accuracy on data with known alpha."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_model import random_dataset, split

import ipromp_pin.promp.likelihood as likelihood
from ipromp_pin.promp import IProMP, direct_loglik
from ipromp_pin.promp.compiled import kernels
from ipromp_pin.promp.posterior import REFINE_NODES, REFINE_WEIGHTS
from ipromp_pin.promp.reference import parabola_vertex, refine_peak


@pytest.mark.parametrize(
    ("use_z", "fuse", "coupling", "n_blocks"),
    [
        (True, True, "all", 1),
        (True, False, "all", 1),
        (False, False, "all", 1),
        (True, True, ["b"], 2),
        (True, False, ["b"], 2),
    ],
)
def test_engine_loglik_equals_textbook_likelihood(
    use_z: bool, fuse: bool, coupling, n_blocks: int, monkeypatch
) -> None:
    # P from the factors, from one Z product per task and block, or from one product for all
    # (fused: here over the union of the tasks' candidate windows, rows a task does not use included)
    monkeypatch.setattr(likelihood, "FUSE_SPAN", 1e9 if fuse else 0.0)
    train, test = split(random_dataset(5, missing_group="a"), 6)
    model = IProMP(["a", "b"], n_basis=8, n_alpha=50, noise=0.5, coupling=coupling).fit(train)
    engine = model.predictor_.engine
    engine.use_z = use_z
    assert (engine.fuse_rows is not None) == fuse
    assert len(set(engine.starts.tolist())) > 1  # the tasks' candidate windows differ
    # independent blocks of observed dims: one per group when only "b" is coupled to the robot
    assert len(engine.blocks) == n_blocks
    assert sorted(np.concatenate([b.dims for b in engine.blocks]).tolist()) == list(range(model.n_obs_dims_))
    obs = test["task0"][1].head(0.4, ["a", "b"])
    parts, t_last = model.predictor_.encode(obs)
    assert len(parts) == 2  # group "a" has missing samples: its own sample set
    fast = engine.log_likelihood([engine.part_stats(p) for p in parts], t_last)
    for i, task in enumerate(model.tasks_):
        m = model.models_[task]
        for j in range(0, m.alpha_grid.size, 7):
            ref = direct_loglik(model.basis_, m, parts, m.alpha_grid[j], model.duration_nominal_s_, 0.5)
            if np.isfinite(ref):
                assert abs(fast[i, j] - ref) <= 1e-8 * max(1.0, abs(ref))
            else:
                assert fast[i, j] == -np.inf


def test_blocks_side_by_side_equal_blocks_apart(monkeypatch) -> None:
    # two blocks of equal rank share their pair arrays (one factorisation call); with no room for
    # sharing each block gets its own arrays: same log likelihoods, one-shot and streaming
    train, test = split(random_dataset(5), 6)
    obs = test["task0"][1].head(0.4, ["a", "b"])
    out = []
    for room in (likelihood.LANE_GROUP_BYTES, 0.0):
        monkeypatch.setattr(likelihood, "LANE_GROUP_BYTES", room)
        model = IProMP(["a", "b"], n_basis=8, n_alpha=50, noise=0.5, coupling=["b"]).fit(train)
        engine = model.predictor_.engine
        assert len(engine.blocks) == 2
        assert len(engine.lane_groups) == (1 if room else 2)
        stream = model.stream()
        for j in range(obs.n_samples):
            rec = stream.update(obs.t[j], {g: obs.groups[g][j] for g in model.observe})
        out.append((model.recognise(obs).phase_log_post, rec.phase_log_post))
    for shared, apart in zip(*out, strict=True):
        finite = np.isfinite(apart)
        assert np.array_equal(finite, np.isfinite(shared))
        assert np.allclose(shared[finite], apart[finite], rtol=1e-12, atol=1e-12)


def test_candidates_shorter_than_the_observation_are_impossible() -> None:
    train, test = split(random_dataset(6), 6)
    model = IProMP(["a", "b"], n_basis=8, n_alpha=50, noise=0.5).fit(train)
    obs = test["task0"][0].head(0.95, ["a", "b"])
    rec = model.recognise(obs)
    short = rec.phase_grid * model.duration_nominal_s_ < obs.t[-1]
    assert short.any()
    assert np.all(np.isneginf(rec.phase_log_post[short]))


def test_refine_peak_finds_vertex_of_a_parabola() -> None:
    grid = np.linspace(0.5, 1.5, 51)
    assert refine_peak(grid, -((grid - 1.0123) ** 2)) == pytest.approx(1.0123, abs=1e-12)
    assert refine_peak(grid, grid) == grid[-1]  # edge: no refinement


def test_phase_estimate_beats_the_prior_on_synthetic_data() -> None:
    from ipromp_pin.readers.synthetic import NOMINAL_DURATION_S, make_synthetic_dataset, true_alpha

    ds = make_synthetic_dataset(n_tasks=3, n_demos=26, seed=3)
    train = type(ds)(ds.root, {t: d[:16] for t, d in ds.demos.items()})
    model = IProMP(["orientation", "emg"]).fit(train)  # noise chosen by leave-one-out CV
    assert model.noise_ratio_ in model.cv_scores_
    err_est, err_prior = [], []
    scale = model.duration_nominal_s_
    for task, demos in ds.demos.items():
        for d in demos[16:]:
            true = d.duration_s / scale
            assert np.isclose(true * scale, true_alpha(d) * NOMINAL_DURATION_S)
            rec = model.recognise(d.head(0.2, model.observe))
            k = rec.tasks.index(task)
            err_est.append(abs(rec.alpha[k] - true) / true)
            err_prior.append(abs(model.models_[task].alpha_mu - true) / true)
    assert np.mean(err_est) < np.mean(err_prior)


def test_compiled_x_inverse_equals_lapack() -> None:
    from ipromp_pin.exceptions import ModelError

    train, _ = split(random_dataset(7), 6)
    engine = IProMP(["a", "b"], n_basis=8, n_alpha=50, noise=0.5).fit(train).predictor_.engine
    rng = np.random.default_rng(0)
    b = rng.normal(size=(13, 9, 5))  # 13 candidates, 9 basis functions, 5 samples: G singular
    gram = np.ascontiguousarray((b @ np.swapaxes(b, 1, 2)).transpose(1, 2, 0))
    xinv, logdet = engine.x_inverse(gram, 0.3)
    x = np.moveaxis(gram, 2, 0) + 0.3 * np.eye(9)
    assert np.allclose(xinv, np.linalg.inv(x), rtol=1e-10, atol=1e-12)
    assert np.allclose(logdet, np.linalg.slogdet(x)[1], rtol=1e-12)
    sub, _ = engine.x_inverse(gram, 0.3, ke=4)  # leading block only
    assert np.allclose(sub, np.linalg.inv(x[:, :4, :4]), rtol=1e-10, atol=1e-12)
    with pytest.raises(ModelError, match="positive definite"):
        engine.x_inverse(gram, -100.0)


def test_compiled_phase_posterior_equals_numpy() -> None:
    rng = np.random.default_rng(1)
    grids = rng.uniform(0.5, 0.7, (5, 1)) + rng.uniform(0.02, 0.04, (5, 1)) * np.arange(30)
    loglik = -50.0 * (grids - rng.uniform(0.8, 1.2, (5, 1))) ** 2 + rng.normal(0, 0.01, (5, 30))
    loglik[1, :5] = -np.inf  # impossible candidates
    loglik[2, :] = -np.inf  # impossible task
    loglik[3, 0] = 10.0  # peak at the edge: no refinement
    loglik[4, 14:] = -np.inf  # peak next to impossible candidates: parabola on the candidates
    prior = -0.5 * ((grids - 1.0) / 0.2) ** 2
    evidence, logpost, alpha = kernels().phase_posterior(loglik, prior, grids, REFINE_WEIGHTS, REFINE_NODES)
    lp = loglik + prior
    rows = [0, 1, 3, 4]
    ref_ev = np.logaddexp.reduce(lp[rows], axis=1)
    assert np.allclose(evidence[rows], ref_ev, rtol=1e-13)
    assert evidence[2] == -np.inf and np.all(logpost[2] == -np.inf)
    assert np.allclose(logpost[rows], lp[rows] - ref_ev[:, None], rtol=1e-12, atol=1e-12)
    assert np.array_equal(alpha[rows], [refine_peak(grids[r], lp[r]) for r in rows])
    assert alpha[3] == grids[3, 0]


def test_refine_peak_interpolates_a_skewed_log_posterior() -> None:
    # log of a skewed (log-normal-like) density: not a parabola, so a parabola through the three best
    # candidates misses its peak; the interpolation between candidates must find it to a fraction of that
    grid = 0.6 + 0.04 * np.arange(25)

    def f(x):
        return -0.5 * (np.log(x / 1.03) / 0.09) ** 2 - 3.0 * np.log(x)

    fine = np.linspace(0.9, 1.2, 300001)
    true = fine[np.argmax(f(fine))]
    lp = f(grid)
    i = int(np.argmax(lp))
    coarse_err = abs(parabola_vertex(*grid[i - 1 : i + 2], *lp[i - 1 : i + 2]) - true)
    err = abs(refine_peak(grid, lp) - true)
    assert coarse_err > 5e-4
    assert err < 0.05 * coarse_err


def test_stream_group_when_every_task_has_every_candidate() -> None:
    # tasks sharing all unique candidates take a shortcut (W_d^T g read in place, no reordering by
    # pair); it must equal the general path, forced here by one extra unique candidate no task uses
    rng = np.random.default_rng(3)
    n_t, n_c, ke, n_k, r = 3, 6, 5, 7, 4
    dims, dim_off = np.array([1, 2, 0]), np.array([0, 2, 3])  # two blocks of 2 and 1 dims
    dg = dims.size
    col_off = np.array([0, r * 2 * n_t, r * dg * n_t])
    w_t = rng.normal(size=(r * dg * n_t + dg * n_t, ke))  # W_d rows, then nu mu_d rows
    y = rng.normal(size=3)
    inv_delta = rng.uniform(0.5, 2.0, size=(n_t, dg))
    log_delta = rng.normal(size=(2, n_t))
    ia, ib = (x.astype(np.int64) for x in np.triu_indices(r))
    unpack = np.zeros((r, r), dtype=np.int64)
    unpack[ia, ib] = unpack[ib, ia] = np.arange(ia.size)
    g = rng.normal(size=(ke, n_c))
    s = rng.uniform(1.0, 2.0, size=n_c)
    proj = rng.normal(size=(n_k, n_c, 3))
    starts = np.zeros(n_t, dtype=np.int64)
    alphas = np.tile(np.linspace(1.0, 1.5, n_c), (n_t, 1))
    extra = (  # the same values with one more unique candidate (last, used by no task)
        np.concatenate([g, rng.normal(size=(ke, 1))], axis=1),
        np.append(s, 1.5),
        np.concatenate([proj, np.ones((n_k, 1, 3))], axis=1),
    )
    outs = []
    for gu, su, pu in ((g, s, proj), extra):
        n_lane = 2 * n_t * n_c
        total, a, pq = np.zeros(n_lane), np.zeros((r, n_lane)), np.zeros((ia.size, n_lane))
        loglik = np.empty((n_t, n_c))
        ok = kernels().stream_group(
            gu, su, y, pu, w_t, dims, dim_off, col_off, 0.7, starts, n_c, inv_delta, log_delta, ia, ib,
            total, a, pq, unpack, alphas, 1.0, 0.5, loglik, False, True,
        )  # fmt: skip
        assert ok
        outs.append((total, a, pq, loglik))
    for fast, general in zip(*outs, strict=True):
        assert np.all(np.isfinite(fast)) and np.any(fast != 0.0)
        assert np.allclose(fast, general, rtol=1e-14, atol=1e-14)
