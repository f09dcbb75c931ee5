"""The separation summary (ipromp_pin.human.separation_summary) that the human checks judge gives the
numbers the full per-pair separation gives, for the first and the slowed re-timings of a motion,
with a tracked human (gaps, as known at a re-plan) and the assumed one, with both kernel backends;
the body placed from its held frames equals the general placement; the compiled CRBA equals
Pinocchio's."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.human.body import BODY_PARTS, HumanMotion, _frame_list
from ipromp_pin.human.iso15066 import arm_mass_matrices, arm_model
from ipromp_pin.human.separation import HAND_REGION, Separation, SeparationAnalyser, sample_groups
from ipromp_pin.human.separation_summary import SeparationSummariser, SeparationSummary
from ipromp_pin.promp.compiled import use_kernels
from ipromp_pin.robot import ee_positions, load_robot

QA = np.array([0.0, -0.6, 0.0, 1.2, 0.0, 0.6, 0.0])
QB = np.array([0.5, -0.2, 0.3, 0.7, 0.2, 0.9, 0.1])
ALLOWED = 0.9


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _motion(t0: float, duration_s: float, k: float = 1.0, dt: float = 0.01):
    """A smooth motion QA -> QB (cosine profile) starting at ``t0``, ``k`` times slower."""
    t = np.arange(0.0, k * duration_s + 1e-9, dt)
    s = 0.5 - 0.5 * np.cos(np.pi * t / (k * duration_s))
    sd = 0.5 * np.pi / (k * duration_s) * np.sin(np.pi * t / (k * duration_s))
    return t0 + t, QA + s[:, None] * (QB - QA), sd[:, None] * (QB - QA)


def _tracked(robot, rng: np.random.Generator) -> HumanMotion:
    """A tracked skeleton in front of the robot's path, its hand reaching to the path's end, with
    occlusions (NaN) of a few frames."""
    frames = _frame_list(BODY_PARTS)
    t = np.arange(0.0, 2.0, 1.0 / 30.0)
    end = ee_positions(robot, QB[None, :])[0]
    base = end + np.array([0.45, 0.05, -0.25])
    offsets = rng.normal(scale=0.25, size=(len(frames), 3))
    pos = base + offsets[None, :, :] + 0.02 * np.sin(3 * t)[:, None, None]
    pos = np.repeat(pos, 1, axis=0)
    hand = frames.index("/left_hand_1")
    pos[:, hand] = end + np.array([0.12, 0.0, 0.0]) + 0.05 * np.cos(2 * t)[:, None]
    pos[10:20, frames.index("/head_1")] = np.nan
    pos[25:, frames.index("/right_elbow_1")] = np.nan
    radii = np.array([p.radius_m for p in BODY_PARTS])
    return HumanMotion(t, tuple(frames), pos, BODY_PARTS, radii, 1.6, 0.15, source="test skeleton")


def _assumed(robot) -> HumanMotion:
    end = ee_positions(robot, QB[None, :])[0]
    t = np.arange(0.0, 2.0, 0.05)
    hand = end + np.array([0.15, 0.0, 0.0]) + 0.03 * np.sin(4 * t)[:, None]
    return HumanMotion.assumed_human(robot.settings.human, t_s=t, hand_m=hand)


def _full(sep: Separation) -> dict:
    """The reductions the checks took of the full separation before the summary."""
    clearance = sep.clearance_m(HAND_REGION)
    n = int(np.argmin(clearance))
    link, part, t, d = sep.where(n, exclude_region=HAND_REGION, nominal=True)
    row = sep.protective_m[n]
    nr = int(np.argmax(sep.max_ratio))
    li, pi = np.unravel_index(int(np.argmax(sep.speed_ratio[nr])), sep.speed_ratio.shape[1:])
    worst = float(sep.speed_ratio[nr, li, pi])
    fast = worst > 0
    return {
        "clearance": (d, link, part, t, float(np.nanmin(row)) if np.any(np.isfinite(row)) else None),
        "within": sep.within_sp.tolist(),
        "max_ratio": sep.max_ratio.tolist(),
        "counts": (int(sep.violation.sum()), int(sep.over(ALLOWED).sum())),
        "ratio": (
            float(sep.t_s[nr]),
            sep.links[li],
            sep.parts[pi],
            worst,
            float(sep.approach_m_s[nr, li, pi]) if fast else None,
            float(sep.robot_mass_kg[nr, li, pi]) if fast else None,
            float(sep.protective_m[nr, li, pi]) if fast else None,
        ),
    }


def _summary(s: SeparationSummary) -> dict:
    (cl, cp), (rl, rp) = s.clearance_pair, s.ratio_pair
    fast = s.worst_ratio > 0
    return {
        "clearance": (
            s.clearance_m,
            s.links[cl],
            s.parts[cp],
            float(s.t_s[s.clearance_sample]),
            s.clearance_protective_m,
        ),
        "within": s.within_sp.tolist(),
        "max_ratio": s.max_ratio.tolist(),
        "counts": (int(s.violation.sum()), int(s.over(ALLOWED).sum())),
        "ratio": (
            float(s.t_s[s.ratio_sample]),
            s.links[rl],
            s.parts[rp],
            s.worst_ratio,
            s.approach_m_s if fast else None,
            s.robot_mass_kg if fast else None,
            s.protective_m if fast else None,
        ),
    }


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        x, y = a[key], b[key]
        assert len(x) == len(y), key
        for u, v in zip(x, y, strict=True):
            if isinstance(u, float) and isinstance(v, float):
                assert v == pytest.approx(u, rel=1e-12, abs=1e-12), key
            else:
                assert u == v, key


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("who", ["tracked", "assumed"])
def test_the_summary_gives_the_full_separations_numbers_for_every_slowed_round(robot, backend, who):
    rng = np.random.default_rng(3)
    human = _tracked(robot, rng) if who == "tracked" else _assumed(robot)
    seen = human.until(0.6)  # as known at a re-plan: every sample of the motion after it
    analyser = SeparationAnalyser(robot)
    summariser = SeparationSummariser(analyser)
    fast_pairs = 0
    with use_kernels(backend):
        for k in (1.0, 1.7, 3.0):  # the first round and slowed re-timings of the same path
            t, q, qd = _motion(0.6, 0.6, k)
            full = analyser.analyse(t, q, qd, seen)
            summary = summariser.summary(t, q, qd, seen)
            _assert_same(_full(full), _summary(summary))
            assert summariser.summary(t, q, qd, seen) is summary  # kept for the next check
            fast_pairs += int(np.count_nonzero(full.speed_ratio))
        # and against the whole recorded human (no horizon: the general placement)
        t, q, qd = _motion(0.3, 0.8)
        _assert_same(_full(analyser.analyse(t, q, qd, human)), _summary(summariser.summary(t, q, qd, human)))
    assert fast_pairs > 0  # the cases exercise the contact-speed ratios


@pytest.mark.parametrize("who", ["tracked", "assumed"])
def test_the_body_from_its_held_frames_equals_the_general_placement(robot, who):
    human = _tracked(robot, np.random.default_rng(5)) if who == "tracked" else _assumed(robot)
    for t_obs in (0.0, 0.4, 0.5, 1.99, 5.0):
        seen = human.until(t_obs)
        t = seen.horizon_s + np.arange(0.0, 1.5, 0.01)
        assert seen._held_capsules(t) is not None
        fast = seen.capsules(t)
        pos, grow = seen.frames_at(t)  # the general path, by hand
        object.__setattr__(seen, "_held_capsules", lambda _t: None)
        general = seen.capsules(t)
        for x, y in zip(fast, general, strict=True):
            np.testing.assert_array_equal(x, y)
        assert np.isfinite(pos).all() and (grow >= 0).all()
    # before the horizon the general placement is used
    assert human.until(1.0)._held_capsules(np.array([0.5, 1.2])) is None


def test_the_compiled_crba_equals_pinocchios(robot):
    q = np.random.default_rng(2).uniform(robot.lower_rad, robot.upper_rad, size=(25, robot.n_joints))
    model = arm_model(robot)
    with use_kernels("numba"):
        compiled = arm_mass_matrices(robot, q, model, compiled=True)
        reference = arm_mass_matrices(robot, q, model)  # Pinocchio's by default
    np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(compiled, np.transpose(compiled, (0, 2, 1)))


def test_the_sample_groups_of_sorted_pairs_are_np_uniques():
    rng = np.random.default_rng(3)
    for n_i in (
        np.sort(rng.integers(0, 40, 200)),  # the kernels' pair order: the sort skipped
        rng.integers(0, 40, 200),  # unsorted: np.unique
        np.array([7]),
        np.array([2, 2, 2]),
        np.array([], dtype=np.int64),
    ):
        samples, which = sample_groups(n_i)
        ref_s, ref_w = np.unique(n_i, return_inverse=True)
        np.testing.assert_array_equal(samples, ref_s)
        np.testing.assert_array_equal(which, ref_w)
        assert samples.dtype == ref_s.dtype
