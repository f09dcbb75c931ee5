"""The two kernel backends (compiled numba, plain numpy) agree, and "auto" never makes a run wait
for the one-time compile (ipromp_pin.promp.compiled, ipromp_pin.promp.warmup)."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.promp import IProMP, compiled, direct_predict, numpy_kernels, warmup
from ipromp_pin.promp.compiled import kernels, use_kernels


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def _fields(p) -> list[np.ndarray]:
    return [p.log_posterior, p.posterior, p.log_evidence, p.alpha, p.q_mean, p.q_cov, p.phase_log_post]


@pytest.mark.parametrize(
    ("seed", "use_z", "coupling"), [(41, True, "auto"), (42, False, ["a"]), (43, True, [])]
)
def test_numpy_kernels_equal_the_compiled_ones_and_the_reference(seed, use_z, coupling):
    train, test = split(random_dataset(seed, n_demos=9, missing_group="b" if seed == 42 else None), 7)
    fits = {}
    for backend in ("numba", "numpy"):
        with use_kernels(backend):
            assert kernels().__name__.endswith("_kernels" if backend == "numba" else "numpy_kernels")
            model = IProMP(["a", "b"], n_basis=7, n_alpha=30, coupling=coupling).fit(train)
            model.predictor_.engine.use_z = use_z
            obs = test["task1"][0].head(0.3, model.observe)
            fits[backend] = (model, model.predict(obs), obs)
    (m_nb, p_nb, obs), (m_np, p_np, _) = fits["numba"], fits["numpy"]
    # fitting chose the same settings (cross-validated with either backend)
    assert m_nb.noise_ratio_ == m_np.noise_ratio_ and m_nb.coupled_groups_ == m_np.coupled_groups_
    assert p_nb.task == p_np.task
    for a, b in zip(_fields(p_np), _fields(p_nb), strict=True):
        assert np.allclose(a, b, rtol=1e-9, atol=1e-9)
    with use_kernels("numpy"):
        ref = direct_predict(m_np.predictor_, obs)
    assert _rel(p_np.posterior, ref.posterior) < 1e-8 and _rel(p_np.q_cov, ref.q_cov) < 1e-8
    assert _rel(p_np.alpha, ref.alpha) < 1e-8 and _rel(p_np.q_mean, ref.q_mean) < 1e-8
    for g in m_np.observe:
        assert _rel(p_np.human_mean[g], ref.human_mean[g]) < 1e-8


def test_streaming_on_the_numpy_backend_uses_the_compiled_streaming_kernels():
    train, test = split(random_dataset(44, n_demos=8), 6)
    model = IProMP(["a", "b"], n_basis=7, n_alpha=25).fit(train)
    demo = test["task0"][0].head(0.4, model.observe)
    results = {}
    for backend in ("numba", "numpy"):
        with use_kernels(backend):
            stream = model.stream()
            for i, t in enumerate(demo.t):
                rec = stream.update(float(t), {g: demo.groups[g][i] for g in demo.groups})
            results[backend] = rec
    assert np.allclose(results["numpy"].log_posterior, results["numba"].log_posterior, atol=1e-9)
    assert numpy_kernels.sherman_morrison.__module__.endswith("_kernels")  # the compiled one
    with pytest.raises(AttributeError):
        numpy_kernels.no_such_kernel  # noqa: B018


@pytest.fixture
def fresh_auto(monkeypatch, tmp_path):
    """The "auto" backend with a private cache folder and a recorded background compile."""
    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path))
    messages, starts = [], []
    monkeypatch.setattr(compiled, "start_background_compile", lambda: starts.append(1) or True)
    monkeypatch.setitem(compiled._state, "modules", {})  # as in a new process
    monkeypatch.setitem(compiled._state, "auto", {})
    compiled.set_announcer(messages.append)
    previous = compiled.set_kernel_backend("auto")
    yield messages, starts
    compiled.set_kernel_backend(previous)
    compiled.set_announcer(None)


def test_auto_runs_on_numpy_while_the_kernels_compile_in_the_background(fresh_auto, monkeypatch):
    messages, starts = fresh_auto
    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    assert kernels() is numpy_kernels
    assert starts == [1] and len(messages) == 1
    assert "numpy version" in messages[0] and f"about {compiled.COMPILE_SECONDS} s, once" in messages[0]
    # decided once per process: it stays on numpy even when the compile has finished meanwhile
    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: True)
    assert kernels() is numpy_kernels and starts == [1] and len(messages) == 1


def test_auto_uses_the_compiled_kernels_when_cached(fresh_auto, monkeypatch):
    messages, starts = fresh_auto
    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: True)
    assert kernels().__name__.endswith("._kernels") and not starts and not messages


def test_one_background_compile_at_a_time_and_none_for_a_day_after_a_failure(monkeypatch, tmp_path):
    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path))
    launched = []

    class FakePopen:
        def __init__(self, args, **kwargs):
            launched.append((args, kwargs))

    monkeypatch.setattr(compiled.subprocess, "Popen", FakePopen)
    assert compiled.start_background_compile()
    args, kwargs = launched[0]
    assert args[1:3] == ["-m", "ipromp_pin.promp.warmup"] and kwargs["stdin"] is compiled.subprocess.DEVNULL
    lock = tmp_path / "kernels" / "compile.lock"
    assert lock.exists()
    assert not compiled.start_background_compile() and len(launched) == 1  # one is running
    old = time.time() - 3600
    os.utime(lock, (old, old))  # a lock left by a killed compile goes stale
    assert compiled.start_background_compile() and len(launched) == 2
    lock.unlink()
    (tmp_path / "kernels" / "compile.failed").write_text("boom")
    assert not compiled.start_background_compile() and len(launched) == 2


def test_warmup_removes_its_lock_and_records_a_failure(monkeypatch, tmp_path, capsys):
    lock = tmp_path / "compile.lock"
    lock.touch()
    monkeypatch.setattr(warmup.os, "nice", lambda n: 0, raising=False)
    monkeypatch.setattr(warmup, "compile_kernels", lambda: 1.5)
    assert warmup.main(["--lock", str(lock)]) == 0 and not lock.exists()
    assert "compiled the inference kernels in 1.5 s" in capsys.readouterr().out

    def fail():
        raise RuntimeError("no compiler")

    lock.touch()
    monkeypatch.setattr(warmup, "compile_kernels", fail)
    assert warmup.main(["--lock", str(lock)]) == 1 and not lock.exists()
    assert "no compiler" in (tmp_path / "compile.failed").read_text()


def test_warmup_compiles_every_kernel_into_the_cache():
    # in the test session numba's cache is warm by now or gets filled here (once)
    assert warmup.compile_kernels() > 0.0
    assert compiled.compiled_kernels_cached(compiled.FIT_PREDICT_KERNELS + warmup.STREAMING_KERNELS)


def test_numba_backend_announces_a_cold_compile(monkeypatch):
    messages = []
    compiled.set_announcer(messages.append)
    monkeypatch.setitem(compiled._state, "modules", {})
    monkeypatch.setitem(compiled._state, "announced", set())
    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    try:
        with use_kernels("numba"):
            kernels()
    finally:
        compiled.set_announcer(None)
    assert messages == [
        f"[kernels] compiling the inference kernels (up to about {compiled.COMPILE_SECONDS} s, once; "
        "cached on disk for the next runs)"
    ]


def test_unknown_backend_is_an_error():
    with pytest.raises(ValueError, match="unknown kernel backend 'gpu'"):
        compiled.set_kernel_backend("gpu")


@pytest.mark.parametrize("case", ["q", "pending", "via_points", "rank0"])
def test_readout_update_kernels_agree_with_dense_conditioning(case):
    # both backends' read-out update against dense Gaussian conditioning of the joints at the
    # prediction's phases, with the precision blockdiag(I, Q), plus pending rows (Woodbury), or a
    # full factor after via-points
    from ipromp_pin.promp.weight_posterior import RobotWeightPosterior

    rng = np.random.default_rng(7)
    nj, k, r, n_m = 3, 5, 0 if case == "rank0" else 4, 6
    phi = rng.uniform(0.0, 1.0, (n_m, k))
    q = rng.normal(size=(r, r))
    q_chol = np.linalg.cholesky(np.eye(r) + q @ q.T)
    rw = RobotWeightPosterior(
        mean=rng.normal(size=(nj, k)), diag=rng.uniform(0.5, 1.5, nj), factor=rng.normal(size=(nj, k, r)),
        q_chol=q_chol, phi=phi, offset=rng.normal(size=nj), scale=rng.uniform(0.5, 2.0, nj),
    )  # fmt: skip
    if case == "via_points":
        rw = rw.condition(phi[:2], np.array([0, 2]), np.array([0.3, -0.2]), np.array([0.1, 0.2]))
    if case == "pending":
        rw, _, _ = rw.readout_update(phi[-1], rng.normal(size=(2, nj)), rng.normal(size=2), np.eye(2) * 0.3)
    readout, values, cov = rng.normal(size=(2, nj)), rng.normal(size=2), np.array([[0.5, 0.1], [0.1, 0.4]])
    # dense reference: latent precision, loadings of the trajectory and of the read-out
    lam_chol = rw.precision_chol()
    lam_inv = np.linalg.inv(lam_chol @ lam_chol.T)
    traj = rw.trajectory_loadings(phi).reshape(rw.n_latent, -1) * np.tile(rw.scale, n_m)[None, :]
    h = (rw.trajectory_loadings(phi[-1:])[:, 0, :] * rw.scale[None, :]) @ readout.T  # (n_u, m)
    s = h.T @ lam_inv @ h + cov
    gain = traj.T @ lam_inv @ h @ np.linalg.inv(s)
    q_end = rw.q_mean(phi[-1:])[0]
    want_mean = gain @ (values - readout @ q_end)
    want_cov = gain @ (h.T @ lam_inv @ traj)
    for backend in ("numba", "numpy"):
        with use_kernels(backend):
            new, d_mean, d_cov = rw.readout_update(phi[-1], readout, values, cov)
        assert np.allclose(d_mean.reshape(-1), want_mean, rtol=1e-10, atol=1e-12)
        dense = want_cov.reshape(n_m, nj, n_m, nj)[np.arange(n_m), :, np.arange(n_m), :]
        assert np.allclose(d_cov, dense, rtol=1e-10, atol=1e-12)
        assert np.allclose(new.q_cov(), rw.q_cov() - d_cov, rtol=1e-9, atol=1e-12)
