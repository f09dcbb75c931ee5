"""The human checks' numpy kernels (ipromp_pin.human.numpy_kernels) equal the numba ones, and the
backend follows the inference kernels' choice (ipromp_pin.human.kernels)."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.human import numpy_kernels as nk
from ipromp_pin.human import separation_kernels as sk
from ipromp_pin.human.body import HumanMotion
from ipromp_pin.human.kernels import human_kernels
from ipromp_pin.human.separation import SeparationAnalyser
from ipromp_pin.promp.compiled import use_kernels
from ipromp_pin.robot import load_robot

TOL = {"rtol": 1e-9, "atol": 1e-9}


def _chain(rng: np.random.Generator, n: int = 40, nj: int = 7, nl: int = 5):
    x0 = np.tile(np.eye(4), (nj, 1, 1))
    for k in range(nj):
        a, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        x0[k, :3, :3] = a * np.sign(np.linalg.det(a))
        x0[k, :3, 3] = rng.normal(scale=0.2, size=3)
    axis = rng.normal(size=(nj, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    anchor = rng.integers(0, nj, size=nl).astype(np.int64)
    a_loc, b_loc = rng.normal(scale=0.1, size=(nl, 3)), rng.normal(scale=0.1, size=(nl, 3))
    b_loc[0] = a_loc[0]  # a sphere among the capsules
    q = rng.uniform(-2.0, 2.0, size=(n, nj))
    return q, x0, axis, anchor, a_loc, b_loc


def _body(rng: np.random.Generator, ra: np.ndarray, rb: np.ndarray, npart: int = 4):
    n = ra.shape[0]
    ha = rng.normal(scale=0.3, size=(n, npart, 3))
    hb = ha + rng.normal(scale=0.2, size=(n, npart, 3))
    hb[:, 0] = ha[:, 0]  # a point-like part
    ha[:3, 1], hb[:3, 1] = ra[:3, 1], rb[:3, 1]  # axes that meet: NaN directions
    hr = rng.uniform(0.02, 0.1, size=(n, npart))
    return ha, hb, hr


def _compare(a: tuple, b: tuple) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.shape == y.shape
        np.testing.assert_allclose(x, y, **TOL)


def test_every_numpy_kernel_equals_the_numba_one():
    rng = np.random.default_rng(7)
    q, x0, axis, anchor, a_loc, b_loc = _chain(rng)
    frames = sk.arm_frames(q, x0, axis, anchor, a_loc, b_loc)
    _compare(nk.arm_frames(q, x0, axis, anchor, a_loc, b_loc), frames)
    origins, axes, ra, rb = frames
    rr = rng.uniform(0.03, 0.08, size=ra.shape[1])
    ha, hb, hr = _body(rng, ra, rb)
    near = sk.capsule_distances(ra, rb, rr, ha, hb, hr)
    _compare(nk.capsule_distances(ra, rb, rr, ha, hb, hr), near)
    dist, cr, ch = near
    qd = rng.normal(size=q.shape)
    qd[0] = 0.0  # a resting arm: zero J^T u rows where the axes meet
    speeds = sk.approach_speeds(dist, cr, ch, rr, origins, axes, qd, anchor, 0.2, 0.3)
    _compare(nk.approach_speeds(dist, cr, ch, rr, origins, axes, qd, anchor, 0.2, 0.3), speeds)
    unit = speeds[2]
    assert np.isnan(unit).any()
    n_i, l_i, p_i = (np.asarray(v, dtype=np.int64) for v in np.nonzero(np.ones(dist.shape, dtype=bool)))
    jtu = sk.pair_jtu(n_i, l_i, p_i, cr, unit, rr, origins, axes, anchor, qd)
    _compare((nk.pair_jtu(n_i, l_i, p_i, cr, unit, rr, origins, axes, anchor, qd),), (jtu,))
    assert np.abs(jtu).max() > 0.1
    m = rng.normal(size=(q.shape[0], 7, 7))
    mass = m @ m.transpose(0, 2, 1) + 0.5 * np.eye(7)
    inv = sk.inverse_effective_masses(mass, n_i, jtu)
    np.testing.assert_allclose(nk.inverse_effective_masses(mass, n_i, jtu), inv, rtol=1e-9, atol=1e-12)
    empty = np.empty((0, 7))
    assert nk.inverse_effective_masses(mass, n_i[:0], empty).shape == (0,)


def test_the_numpy_backend_gives_the_same_separation_as_numba():
    robot = load_robot("baxter_left")
    t = np.linspace(0.0, 1.0, 25)
    mid = 0.5 * (robot.lower_rad + robot.upper_rad)
    q = mid + 0.6 * np.sin(2.0 * np.pi * t)[:, None] * np.linspace(0.3, 1.0, robot.n_joints)
    qd = np.gradient(q, t, axis=0) * 4.0  # fast enough for contact-speed pairs
    human = HumanMotion.assumed_human(t_s=t)
    results = {}
    for backend in ("numba", "numpy"):
        with use_kernels(backend):
            assert human_kernels().__name__.endswith(
                {"numba": "separation_kernels", "numpy": "numpy_kernels"}[backend]
            )
            results[backend] = SeparationAnalyser(robot).analyse(t, q, qd, human)
    a, b = results["numba"], results["numpy"]
    for field in ("distance_m", "approach_m_s", "protective_m", "speed_ratio", "robot_mass_kg"):
        np.testing.assert_allclose(getattr(b, field), getattr(a, field), equal_nan=True, **TOL)
    np.testing.assert_allclose(b.closest_robot_m, a.closest_robot_m, **TOL)
    assert np.isfinite(a.distance_m).all() and (a.speed_ratio > 0).sum() > 10  # the contact path ran


@pytest.mark.parametrize("cached", [True, False])
def test_auto_decides_the_human_set_from_its_own_cache(monkeypatch, tmp_path, cached):
    from ipromp_pin.promp import compiled

    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path))
    starts, messages = [], []
    monkeypatch.setattr(compiled, "start_background_compile", lambda: starts.append(1) or True)
    monkeypatch.setattr(
        compiled, "kernels_cached", lambda name="inference", names=None: name == "inference" or cached
    )
    compiled.set_announcer(messages.append)
    try:
        with use_kernels("auto"):
            assert compiled.kernels().__name__.endswith("promp._kernels")  # cached: compiled
            assert human_kernels() is (sk if cached else nk)
            assert human_kernels() is (sk if cached else nk)  # decided once
    finally:
        compiled.set_announcer(None)
    # not compiled yet: numpy while the one background compile (every set) runs, said once
    assert starts == ([] if cached else [1]) and len(messages) == (0 if cached else 1)
    if not cached:
        assert "human-check kernels are not compiled yet" in messages[0]


def test_one_switch_for_every_kernel_set():
    from ipromp_pin.promp import compiled

    assert set(compiled.kernel_sets()) >= {"inference", "human"}
    with use_kernels("numpy"):
        assert compiled.kernels().__name__ == "ipromp_pin.promp.numpy_kernels"
        assert human_kernels() is nk
    with use_kernels("numba"):
        assert human_kernels() is sk and compiled.active_backend("human") == "numba"


def test_the_background_compile_also_compiles_the_human_kernels(monkeypatch, tmp_path):
    from ipromp_pin.promp import compiled

    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path))
    launched = []
    monkeypatch.setattr(compiled.subprocess, "Popen", lambda args, **kwargs: launched.append(args))
    assert compiled.start_background_compile()
    assert "--also=ipromp_pin.human.warmup" in launched[0]  # registered when ipromp_pin.human.kernels loads


def test_the_summary_kernels_block_bounds_skip_no_pair_that_matters():
    """A long, smooth motion of a chain past a slowly moving body: many blocks of
    ``separation_kernels.BLOCK`` samples, pairs near and far, slow and fast. The compiled summary,
    which skips the pairs its block bounds settle, finds the same samples within S_p, the same fast
    pairs in the same order with the same numbers, and the same closest sample as the numpy one
    that computes every pair."""
    rng = np.random.default_rng(11)
    q, x0, axis, anchor, a_loc, b_loc = _chain(rng, n=2, nl=6)
    n = 40 * sk.BLOCK + 3
    s = np.linspace(0.0, 1.0, n)[:, None]
    q = q[0] + s * (q[1] - q[0])
    qd = np.gradient(q, 0.01, axis=0)
    origins, axes, ra, rb = sk.arm_frames(q, x0, axis, anchor, a_loc, b_loc)
    rr = rng.uniform(0.03, 0.08, size=ra.shape[1])
    centre = ra.mean(axis=(0, 1))
    npart = 6
    away = np.array([1.0, 0.5, 0.2]) * 2.0 * s[:, :, None]  # the body leaves the chain's reach
    ha = centre + rng.normal(scale=0.3, size=(npart, 3)) + away
    hb = ha + rng.normal(scale=0.1, size=(npart, 3))
    hr = np.ascontiguousarray(np.tile(rng.uniform(0.03, 0.1, size=npart), (n, 1)) + 0.02 * s)
    body_r = hr[0] - 0.01
    nominal = np.array([True, True, False, True, True, True])
    floor = np.array([0.05, 0.3, 0.1, 0.2, 1.0, 0.02])
    args = (ra, rb, rr, ha, hb, hr, body_r, nominal, floor, origins, axes, qd, anchor, 0.25, 0.15)
    fast = sk.separation_summary(*args)
    every = nk.separation_summary(*args)
    clear, within, n_i, l_i, p_i = fast[:5]
    assert np.array_equal(within, every[1]) and within.any() and not within.all()
    for x, y in zip(fast[2:5], every[2:5], strict=True):
        assert np.array_equal(x, y)
    for x, y in zip(fast[5:], every[5:], strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    assert 0 < n_i.size < n * ra.shape[1] * npart // 4  # some pairs are fast, most are not
    nc = int(np.argmin(clear))
    assert nc == int(np.argmin(every[0])) and clear[nc] == pytest.approx(every[0][nc], rel=1e-12)
    assert np.all(clear >= every[0] - 1e-12)  # elsewhere at least the true clearance


def test_a_preferred_backend_holds_only_for_an_undecided_set_under_auto():
    from ipromp_pin.promp import compiled

    with use_kernels("auto"):
        assert compiled.prefer_backend("inference", "numpy") == "numpy"
        assert compiled.kernels().__name__ == "ipromp_pin.promp.numpy_kernels"
        assert compiled.prefer_backend("inference", "numba") == "numpy"  # decided: kept for the process
    with use_kernels("numba"):
        assert compiled.prefer_backend("inference", "numpy") == "numba"  # not auto: the backend holds
    with pytest.raises(ValueError, match="unknown kernel backend"):
        compiled.prefer_backend("inference", "auto")
