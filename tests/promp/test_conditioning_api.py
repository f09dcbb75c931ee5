"""Conditioning a prediction on joint via-points, the current state and a goal pose; sampling a task's
prior; batch prediction; scikit-learn's clone and grid search.

The via-point update works on the weights in latent form; it is checked against the textbook
Gaussian conditioning of the dense weight covariance.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.exceptions import DataError, InfeasibleError, ModelError
from ipromp_pin.planning.goal import condition_on_goal_pose
from ipromp_pin.promp import IProMP
from ipromp_pin.robot import forward_kinematics, load_robot, solve_ik


@pytest.fixture(scope="module")
def setup():
    train, test = split(random_dataset(21), 6)
    model = IProMP(["a", "b"], n_basis=9, noise=30.0, coupling="all").fit(train)
    return model, train, test, model.predict(test["task1"][0].head(0.3, ["a", "b"]))


def _dense(rw):
    """Dense weight mean (J K,) and covariance (J K, J K) of a latent-form posterior."""
    j, k, r = rw.factor.shape
    g = np.zeros((j * k, j * k + r))
    g[:, : j * k] = np.diag(np.repeat(np.sqrt(rw.diag), k))
    g[:, j * k :] = rw.factor.reshape(j * k, r)
    lam = rw.precision_chol() @ rw.precision_chol().T
    return rw.mean.reshape(-1), g @ np.linalg.solve(lam, g.T)


def _textbook(pred, rows, joints, values, std, deriv):
    """Kalman update of the dense weights, then the trajectory mean (M, J) and covariance (M, J, J)."""
    rw = pred.robot_weights
    j, k, _ = rw.factor.shape
    mean, cov = _dense(rw)
    h = np.zeros((len(values), j * k))
    for i, (row, jj) in enumerate(zip(rows, joints, strict=True)):
        h[i, jj * k : (jj + 1) * k] = row
    y = (np.asarray(values) - np.where(deriv, 0.0, rw.offset[joints])) / rw.scale[joints]
    r = np.diag((np.asarray(std) / rw.scale[joints]) ** 2)
    gain = cov @ h.T @ np.linalg.inv(h @ cov @ h.T + r)
    mean = mean + gain @ (y - h @ mean)
    cov = cov - gain @ h @ cov
    p = np.zeros((rw.phi.shape[0], j, j * k))
    for jj in range(j):
        p[:, jj, jj * k : (jj + 1) * k] = rw.phi
    q_mean = np.einsum("mjw,w->mj", p, mean) * rw.scale + rw.offset
    q_cov = np.einsum("miw,wv,mjv->mij", p, cov, p) * np.outer(rw.scale, rw.scale)
    return q_mean, q_cov


def test_latent_form_gives_the_predictions_covariance(setup):
    *_, pred = setup
    rw = pred.robot_weights
    np.testing.assert_allclose(rw.q_cov(), pred.q_cov, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(rw.q_mean(), pred.q_mean, rtol=1e-12, atol=1e-12)


def test_via_points_equal_textbook_gaussian_conditioning(setup):
    *_, pred = setup
    t = np.array([0.4, 1.0]) * pred.duration_s
    q = np.array([[0.3, np.nan, -0.2], [0.1, 0.2, np.nan]])
    out = pred.condition_joints(t, q, std_rad=[[0.01, 1.0, 0.02], [0.005, 0.01, 1.0]])
    basis = pred.robot_weights.basis
    rows = basis(np.array([0.4, 0.4, 1.0, 1.0]))
    ref_mean, ref_cov = _textbook(
        pred,
        rows,
        np.array([0, 2, 0, 1]),
        [0.3, -0.2, 0.1, 0.2],
        [0.01, 0.02, 0.005, 0.01],
        np.zeros(4, bool),
    )
    np.testing.assert_allclose(out.q_mean, ref_mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(out.q_cov, ref_cov, rtol=0, atol=1e-10 * np.abs(ref_cov).max())
    # the covariance shrinks, stays symmetric positive semi-definite, and the task estimate is kept
    var0 = np.diagonal(pred.q_cov, axis1=1, axis2=2)
    var1 = np.diagonal(out.q_cov, axis1=1, axis2=2)
    assert np.all(var1 <= var0 + 1e-15) and var1[-1, 0] < 0.05 * var0[-1, 0]
    assert np.min(np.linalg.eigvalsh(out.q_cov)) > -1e-12 * np.abs(out.q_cov).max()
    assert out.task == pred.task and np.array_equal(out.posterior, pred.posterior)
    # one via-point at a time gives the same posterior
    step = pred.condition_joints(t[0], [0.3, -0.2], std_rad=[0.01, 0.02], joints=["j0", "j2"])
    step = step.condition_joints(t[1], [0.1, 0.2], std_rad=[0.005, 0.01], joints=[0, 1])
    np.testing.assert_allclose(step.q_mean, out.q_mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(step.q_cov, out.q_cov, rtol=0, atol=1e-10 * np.abs(out.q_cov).max())


def test_current_state_with_velocity_matches_textbook_and_samples_follow(setup):
    *_, pred = setup
    t_now = pred.observed_until_s
    q_now = np.array([0.1, -0.1, 0.2])
    qd_now = np.array([0.0, 0.5, -0.2])
    out = pred.condition_state(q_now, qd_now, std_rad=1e-3, std_rad_s=1e-2)
    basis = pred.robot_weights.basis
    z = t_now / pred.duration_s
    rows = np.vstack([basis(np.full(3, z)), basis.derivative(np.full(3, z)) / pred.duration_s])
    deriv = np.repeat([False, True], 3)
    ref_mean, ref_cov = _textbook(
        pred, rows, np.tile(np.arange(3), 2), np.r_[q_now, qd_now], np.repeat([1e-3, 1e-2], 3), deriv
    )
    np.testing.assert_allclose(out.q_mean, ref_mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.q_cov, ref_cov, rtol=0, atol=1e-9 * np.abs(ref_cov).max())
    # the conditioned mean passes through the state, and its slope there is the velocity
    w = out.robot_weights
    np.testing.assert_allclose(w.q_mean(basis(np.array([z])))[0], q_now, atol=5e-3)
    slope = (basis.derivative(np.array([z])) / pred.duration_s) @ w.mean.T * w.scale
    np.testing.assert_allclose(slope[0], qd_now, atol=0.05)
    # samples are drawn from the conditioned Gaussian (information form)
    s = out.sample_q(4000, rng=1)
    np.testing.assert_allclose(s.mean(axis=0), out.q_mean, atol=4 * np.sqrt(out.q_cov.max() / 4000) + 1e-9)
    sd = np.sqrt(np.diagonal(out.q_cov, axis1=1, axis2=2))
    big = sd > 1e-3
    assert np.all(np.abs(s.std(axis=0)[big] / sd[big] - 1) < 0.1)


def test_bad_via_points_fail_clearly(setup):
    *_, pred = setup
    with pytest.raises(DataError, match="t_s"):
        pred.condition_joints(pred.duration_s * 1.5, [0.0, 0.0, 0.0])
    with pytest.raises(DataError, match="expected shape"):
        pred.condition_joints([0.1, 0.2], [0.0, 0.0, 0.0])
    with pytest.raises(ModelError, match="positive"):
        pred.condition_joints(0.1, [0.0, 0.0, 0.0], std_rad=0.0)
    with pytest.raises(DataError, match="unknown joints"):
        pred.condition_joints(0.1, [0.0], joints=["left_s0"])


def test_goal_pose_through_inverse_kinematics():
    robot = load_robot("baxter_left")
    rng = np.random.default_rng(4)
    q0 = np.array([-0.84, -0.97, 0.38, 1.26, -0.20, 1.19, 1.66])
    for _ in range(3):
        pose = forward_kinematics(robot, q0 + rng.normal(0, 0.3, 7))[0]
        full = solve_ik(robot, pose[:3], pose[3:], q_seed=q0)
        assert full.converged and full.position_error_m < 1e-4 and full.rotation_error_rad < 1e-3
        got = forward_kinematics(robot, full.q)[0]
        assert np.linalg.norm(got[:3] - pose[:3]) < 1e-4 and abs(abs(got[3:] @ pose[3:]) - 1) < 1e-6
        assert solve_ik(robot, pose[:3], q_seed=q0).converged
    far = solve_ik(robot, np.array([3.0, 0.0, 0.0]), q_seed=q0)
    assert not far.converged and far.position_error_m > 1.0

    # a prediction over Baxter's joints, conditioned on a goal pose, reaches it
    from ipromp_pin.readers.synthetic import make_synthetic_dataset

    data = make_synthetic_dataset(n_demos=6, seed=2)
    model = IProMP(["orientation"], noise=30.0, coupling="all").fit(
        [d for t in data.tasks for d in data.demos[t][:-1]]
    )
    pred = model.predict(data.demos["rod"][-1].head(0.2, ["orientation"]))
    goal = forward_kinematics(robot, pred.q_mean[-1] + 0.1)[0]
    out = condition_on_goal_pose(pred, robot, goal[:3], goal[3:])
    reached = forward_kinematics(robot, out.prediction.q_mean[-1])[0]
    assert np.linalg.norm(reached[:3] - goal[:3]) < 5e-3 and out.t_s == pred.duration_s
    assert np.linalg.norm(forward_kinematics(robot, pred.q_mean[-1])[0][:3] - goal[:3]) > 0.05
    with pytest.raises(InfeasibleError, match="out of reach"):
        condition_on_goal_pose(pred, robot, np.array([3.0, 0.0, 0.0]))


def test_sampling_a_tasks_prior(setup):
    model, *_ = setup
    drawn = model.sample_prior("task2", 400, random_state=0)
    assert len(drawn) == 400 and {d.task for d in drawn} == {"task2"}
    assert drawn[0].groups["robot"].shape == (model.n_points, 3) and set(drawn[0].groups) == {
        "a",
        "b",
        "robot",
    }
    m = model.models_["task2"]
    durations = np.array([d.t[-1] for d in drawn]) / model.duration_nominal_s_
    assert durations.min() >= m.alpha_grid[0] and durations.max() <= m.alpha_grid[-1]
    assert abs(durations.mean() - m.alpha_mu) < 4 * m.alpha_sigma / np.sqrt(400)
    # the samples' mean and spread are the learned distribution's (at equal phases)
    z = np.linspace(0, 1, model.n_points)
    mean, std, _ = model.distribution("task2", z)
    values = np.stack([np.hstack([d.groups[g] for g in ("a", "b", "robot")]) for d in drawn])
    np.testing.assert_allclose(values.mean(axis=0), mean, atol=float(4 * std.max() / np.sqrt(400)))
    assert np.all(np.abs(values.std(axis=0) / std - 1) < 0.2)
    with pytest.raises(ModelError, match="unknown task"):
        model.sample_prior("juggling", 2)


def test_batch_prediction_equals_one_at_a_time(setup):
    model, _, test, _ = setup
    obs = [d.head(0.3, ["a", "b"]) for t in test for d in test[t][:1]]
    batch = model.predict(obs)
    assert isinstance(batch, list) and len(batch) == len(obs)
    for o, b in zip(obs, batch, strict=True):
        one = model.predict(o)
        assert one.task == b.task and np.array_equal(one.q_mean, b.q_mean)
    assert [r.task for r in model.recognise(obs)] == [b.task for b in batch]
    with pytest.raises(ModelError, match="sequence of Demo"):
        model.predict([obs[0], "not a demo"])


def test_sklearn_clone_and_grid_search(setup):
    sklearn_base = pytest.importorskip("sklearn.base")
    from sklearn.model_selection import GridSearchCV, StratifiedKFold

    model, train, test, _ = setup
    fresh = sklearn_base.clone(model)
    assert fresh.get_params() == model.get_params() and not hasattr(fresh, "tasks_")
    demos = train.all_demos() + [d for t in test for d in test[t]]
    labels = [d.task for d in demos]
    search = GridSearchCV(
        IProMP(["a", "b"], n_basis=9, coupling="all", head=False, handover=False),
        {"noise": [0.1, 30.0], "n_basis": [5, 9]},
        cv=StratifiedKFold(3, shuffle=True, random_state=0),
        error_score="raise",
    ).fit(demos, labels)
    assert len(search.cv_results_["params"]) == 4
    assert search.best_estimator_.tasks_ == ["task0", "task1", "task2"]
    assert 0.0 <= search.best_score_ <= 1.0
    assert search.score(demos, labels) == search.best_estimator_.score(demos)
    with pytest.raises(ModelError, match="y says"):
        IProMP(["a", "b"]).fit(demos, labels[::-1])
