"""Checks of a fitted model: every number finite, every variance positive, every shape consistent.

:func:`check_fitted` runs after :meth:`IProMP.fit <ipromp_pin.promp.estimator.IProMP.fit>` (a model
that learned infinite scales from absurd data must not be used or saved), before a model file is
written and after one is read (:mod:`~ipromp_pin.promp.serialization`, which also refuses unknown
and oversized arrays before loading them). It raises :class:`~ipromp_pin.exceptions.ModelError`
naming the task, the array and the problem; the serialization turns that into a
:class:`~ipromp_pin.exceptions.ModelFileError` naming the file.

The checks cost well under a millisecond for the models of this project (a few hundred thousand
numbers): they are vectorised reductions over each array once.
"""

from __future__ import annotations

from typing import SupportsFloat, cast

import numpy as np

from ..exceptions import ModelError
from .fitted import FittedModel
from .handover import HandoverRegression
from .handover_orientation import OrientationEstimate
from .head import RecognitionHead
from .novelty import check_novelty

MAX_DURATION_S = 86400.0
"""Largest nominal duration ``T_norm`` of a model in [s] (one day: hand-overs last seconds)."""

LOG_PRIOR_TOLERANCE = 1e-6
"""How far the log-sum-exp of a normalised log prior may be from 0."""

MAX_SCALED = 1e6
"""Largest magnitude of a model array in scaled units (weights, their variances and factors,
residual variances): the channels are scaled to unit variance, so their weights are of order 1;
a million is far beyond any fit and far below what overflows the inference's sums."""

MAX_ORIGINAL = 1e12
"""Largest magnitude of the channel scaling (offsets, scales, log shifts) in the channels' own units."""

MAX_PHASE = 100.0
"""Largest phase ratio ``alpha = T / T_norm`` (and its prior's spread): a task's demos last a few
times ``T_norm`` at most (the readers refuse durations beyond 3 times their task's median)."""


def _fail(where: str, problem: str) -> ModelError:
    return ModelError(f"{where}: {problem}")


def _array(where: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (None: any length), else ModelError."""
    a = np.asarray(value)
    if a.dtype != np.float64:
        raise _fail(where, f"must hold float64 numbers, holds {a.dtype}")
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise _fail(where, f"has shape {a.shape}, expected {want}")
    return a


def _finite(where: str, a: np.ndarray) -> None:
    if not np.isfinite(a).all():
        bad = int(np.count_nonzero(~np.isfinite(a)))
        raise _fail(where, f"{bad} NaN or infinite values")


def _bounded(where: str, a: np.ndarray, bound: float) -> None:
    _finite(where, a)
    big = np.abs(a) > bound
    if big.any():
        raise _fail(where, f"implausible value {a[big].flat[0]:g} (magnitude above {bound:g})")


def _positive(where: str, a: np.ndarray, allow_zero: bool = False, bound: float = np.inf) -> None:
    _bounded(where, a, bound)
    bad = a < 0 if allow_zero else a <= 0
    if bad.any():
        raise _fail(where, f"{'negative' if allow_zero else 'zero or negative'} value {a[bad].flat[0]:g}")


def _scalar(where: str, value: object, low: float, high: float, low_open: bool = True) -> None:
    try:
        v = float(cast("SupportsFloat | str", value))  # anything else raises TypeError, caught here
    except (TypeError, ValueError):
        raise _fail(where, f"must be a number, got {value!r}") from None
    ok = (v > low if low_open else v >= low) and v <= high
    if not (np.isfinite(v) and ok):
        raise _fail(where, f"must be in {'(' if low_open else '['}{low:g}, {high:g}], got {v!r}")


def _log_prior(where: str, a: np.ndarray) -> None:
    if np.isnan(a).any() or (a > 0).any() or not np.isfinite(a).any():
        raise _fail(where, "must be log probabilities (<= 0, at least one finite, no NaN)")
    total = float(np.logaddexp.reduce(a))
    if abs(total) > LOG_PRIOR_TOLERANCE:
        raise _fail(where, f"probabilities sum to {np.exp(total):.6g}, not 1")


def check_fitted(fitted: FittedModel) -> FittedModel:
    """Check a fitted model's numbers and shapes; returns it unchanged.

    Raises:
        ModelError: the first problem found, naming the array (and task).
    """
    layout, basis = fitted.layout, fitted.basis
    d, k = layout.n_dims, basis.n_basis
    if d < 1 or layout.n_obs_dims < 1:
        raise _fail("layout", "a model needs observed channels and robot joints")
    for g, names in layout.channel_names.items():
        if len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
            raise _fail(f"channel names of '{g}'", f"must be distinct non-empty strings, got {list(names)}")
    if len(set(layout.groups)) != len(layout.groups):
        raise _fail("groups", f"a group is listed twice in {list(layout.groups)}")
    sc = fitted.scaler
    _bounded("scaler_offset", _array("scaler_offset", sc.offset, (d,)), MAX_ORIGINAL)
    _positive("scaler_scale", _array("scaler_scale", sc.scale, (d,)), bound=MAX_ORIGINAL)
    shift = _array("scaler_log_shift", sc.log_shift, (d,))
    log = np.isfinite(shift)
    if np.isinf(shift).any() or (shift[log] <= 0).any() or (shift[log] > MAX_ORIGINAL).any():
        raise _fail("scaler_log_shift", "must be positive for log-scaled channels and NaN for the others")
    if log[layout.robot_slice].any():
        raise _fail("scaler_log_shift", "the robot's joints cannot be log-scaled")
    tasks = fitted.tasks
    if not tasks or len(set(tasks)) != len(tasks) or not all(isinstance(t, str) and t for t in tasks):
        raise _fail("tasks", f"must be distinct non-empty names, got {list(tasks)}")
    if set(fitted.models) != set(tasks):
        raise _fail("tasks", "task models do not match the task names")
    _log_prior("task_log_prior", _array("task_log_prior", fitted.task_log_prior, (len(tasks),)))
    _scalar("duration_nominal_s", fitted.duration_nominal_s, 0.0, MAX_DURATION_S)
    _scalar("noise_ratio", fitted.noise_ratio, 0.0, np.finfo(float).max)
    coupled = list(fitted.coupled_groups)
    if len(set(coupled)) != len(coupled) or any(g not in layout.observe for g in coupled):
        raise _fail("coupled_groups", f"{coupled} must be distinct observed groups {list(layout.observe)}")
    _positive("residual_var", _array("residual_var", fitted.residual_var, (d,)), True, MAX_SCALED)
    n_blocks = 1 + any(g not in coupled for g in layout.observe)  # see training.coupling_blocks
    # a covariance pooled over tasks (``pooling`` > 0) has at most the rank of every task's demos
    n_all = sum(int(np.shape(m.train_weights)[0]) for m in fitted.models.values())
    n_cand = None
    for t in tasks:
        m = fitted.models[t]
        w = f"task '{t}'"
        _bounded(f"{w} mean", _array(f"{w} mean", m.mean, (d, k)), MAX_SCALED)
        _positive(f"{w} diag", _array(f"{w} diag", m.diag, (d,)), bound=MAX_SCALED)
        factor = _array(f"{w} factor", m.factor, (d, k, None))
        _bounded(f"{w} factor", factor, MAX_SCALED)
        shrink = _array(f"{w} shrinkage", m.shrinkage, (d,))
        _finite(f"{w} shrinkage", shrink)
        if ((shrink < 0) | (shrink > 1)).any():
            raise _fail(f"{w} shrinkage", "intensities must lie in [0, 1]")
        _scalar(f"{w} alpha_mu", m.alpha_mu, 0.0, MAX_PHASE)
        _scalar(f"{w} alpha_sigma", m.alpha_sigma, 0.0, MAX_PHASE)
        grid = _array(f"{w} alpha_grid", m.alpha_grid, (None,))
        _positive(f"{w} alpha_grid", grid, bound=MAX_PHASE)
        if grid.size < 1 or (np.diff(grid) <= 0).any():
            raise _fail(f"{w} alpha_grid", "phase candidates must be increasing")
        if n_cand is not None and grid.size != n_cand:
            raise _fail(f"{w} alpha_grid", f"{grid.size} phase candidates, other tasks have {n_cand}")
        n_cand = grid.size
        _log_prior(f"{w} alpha_log_prior", _array(f"{w} alpha_log_prior", m.alpha_log_prior, (grid.size,)))
        weights = _array(f"{w} train_weights", m.train_weights, (None, d, k))
        _bounded(f"{w} train_weights", weights, MAX_SCALED)
        n = weights.shape[0]
        if n < 2:
            raise _fail(f"{w} train_weights", f"{n} training demo(s); a task needs at least 2")
        _positive(f"{w} train_alpha", _array(f"{w} train_alpha", m.train_alpha, (n,)), bound=MAX_PHASE)
        if factor.shape[2] > max(n_all - 1, 1) * n_blocks:
            raise _fail(f"{w} factor", f"rank {factor.shape[2]} exceeds what {n_all} demos can give")
    added = tuple(fitted.added_tasks)
    if added != tuple(tasks[len(tasks) - len(added) :]) or len(added) >= len(tasks):
        raise _fail("added_tasks", f"must be the last tasks and leave a fitted one, got {list(added)}")
    n_fit = fitted.n_fit_tasks  # the head and the hand-over estimates cover the fitted tasks only
    if fitted.head is not None:
        _check_head(fitted.head, n_fit, layout.n_obs_dims)
    if fitted.handover is not None:
        _check_handover(fitted.handover, n_fit, layout.n_obs_dims, d - layout.n_obs_dims)
    if fitted.orientation is not None:
        _check_orientation(fitted.orientation, n_fit, d - layout.n_obs_dims)
    if fitted.novelty is not None:
        try:
            check_novelty(fitted.novelty, len(tasks), layout.n_obs_dims)
        except ValueError as exc:
            raise _fail("novelty", str(exc)) from None
    return fitted


def _increasing_fractions(where: str, ratios: np.ndarray) -> None:
    _finite(where, ratios)
    if ratios.size < 1 or (np.diff(ratios) <= 0).any() or (ratios <= 0).any() or (ratios > 1).any():
        raise _fail(where, "must be increasing observed fractions in (0, 1]")


def _check_head(head: RecognitionHead, n_tasks: int, n_obs: int) -> None:
    """The recognition head's arrays: shapes, finite numbers, positive scales, known model codes."""
    ratios = _array("head ratios", head.ratios, (None,))
    _increasing_fractions("head ratios", ratios)
    r, f = ratios.size, 3 * n_obs + n_tasks
    _bounded("head coef", _array("head coef", head.coef, (r, n_tasks, f)), MAX_SCALED)
    _bounded("head intercept", _array("head intercept", head.intercept, (r, n_tasks)), MAX_SCALED)
    _bounded("head feature_mean", _array("head feature_mean", head.feature_mean, (r, f)), MAX_SCALED)
    _positive(
        "head feature_scale", _array("head feature_scale", head.feature_scale, (r, f)), bound=MAX_SCALED
    )
    _positive("head c", _array("head c", head.c, (r,)), bound=MAX_SCALED)
    for name, value in (("kind", head.kind), ("generative", head.generative)):
        if value is not None:
            codes = _array(f"head {name}", value, (r,))
            if not np.isin(codes, (0.0, 1.0)).all():
                raise _fail(f"head {name}", "codes must be 0 or 1")


def _check_handover(ho: HandoverRegression, n_tasks: int, n_obs: int, n_joints: int) -> None:
    """The hand-over regression's arrays: shapes, finite numbers, observed feature dims, positive
    definite residual covariances, a positive trust factor."""
    ratios = _array("handover ratios", ho.ratios, (None,))
    _increasing_fractions("handover ratios", ratios)
    dims = np.asarray(ho.dims)
    if dims.ndim != 1 or dims.size < 1 or dims.dtype.kind != "i" or (dims < 0).any() or (dims >= n_obs).any():
        raise _fail("handover dims", f"must be observed dims in [0, {n_obs}), got {dims.tolist()}")
    r, f = ratios.size, dims.size
    readout = _array("handover readout", ho.readout, (n_tasks, None, n_joints))
    m = readout.shape[1]
    _bounded("handover readout", readout, MAX_ORIGINAL)
    _bounded("handover coef", _array("handover coef", ho.coef, (r, n_tasks, m, 2 * f)), MAX_ORIGINAL)
    _bounded("handover intercept", _array("handover intercept", ho.intercept, (r, n_tasks, m)), MAX_ORIGINAL)
    _covariances("handover residual_cov", _array("handover residual_cov", ho.residual_cov, (r, m, m)))
    _scalar("handover trust", ho.trust, 0.0, MAX_ORIGINAL)
    if ho.kind is not None:
        _check_neighbours(ho, r, n_tasks, m, 2 * f)


def _covariances(where: str, cov: np.ndarray) -> None:
    """A stack of covariance matrices (..., M, M): bounded, symmetric and positive definite."""
    _bounded(where, cov, MAX_ORIGINAL)
    if not np.allclose(cov, np.swapaxes(cov, -1, -2), rtol=1e-9, atol=0.0):
        raise _fail(where, "must be symmetric")
    if (np.linalg.eigvalsh(cov) <= 0).any():
        raise _fail(where, "must be positive definite")


def _check_orientation(est: OrientationEstimate, n_tasks: int, n_joints: int) -> None:
    """The orientation estimate's arrays: shapes, finite numbers, symmetric positive definite noise
    covariances, a positive trust factor."""
    for name in ("position_readout", "rotation_readout"):
        _bounded(
            f"orientation {name}",
            _array(f"orientation {name}", getattr(est, name), (n_tasks, 3, n_joints)),
            MAX_ORIGINAL,
        )
    _bounded("orientation target", _array("orientation target", est.target, (n_tasks, 3)), MAX_ORIGINAL)
    _covariances("orientation noise_cov", _array("orientation noise_cov", est.noise_cov, (n_tasks, 3, 3)))
    _scalar("orientation trust", est.trust, 0.0, MAX_ORIGINAL)


def _check_neighbours(ho: HandoverRegression, r: int, n_tasks: int, m: int, n_feat: int) -> None:
    """The hand-over's k-nearest-neighbour arrays: shapes, finite numbers, 0/1 codes, row counts in
    ``[0, N]`` (at least 1 at the k-nearest-neighbour fractions), whole numbers of neighbours at least
    1, positive scales."""
    kind = _array("handover kind", ho.kind, (r,))
    if not np.isin(kind, (0.0, 1.0)).all():
        raise _fail("handover kind", "codes must be 0 or 1")
    for name in ("neighbour_x", "neighbour_y", "neighbour_mean", "neighbour_scale"):
        if getattr(ho, name) is None:
            raise _fail(f"handover {name}", "is missing")
    x = _array("handover neighbour_x", ho.neighbour_x, (r, n_tasks, None, n_feat))
    n_rows = x.shape[2]
    _bounded("handover neighbour_x", x, MAX_ORIGINAL)
    _bounded(
        "handover neighbour_y",
        _array("handover neighbour_y", ho.neighbour_y, (r, n_tasks, n_rows, m)),
        MAX_ORIGINAL,
    )
    _bounded(
        "handover neighbour_mean",
        _array("handover neighbour_mean", ho.neighbour_mean, (r, n_tasks, n_feat)),
        MAX_ORIGINAL,
    )
    _positive(
        "handover neighbour_scale",
        _array("handover neighbour_scale", ho.neighbour_scale, (r, n_tasks, n_feat)),
        bound=MAX_ORIGINAL,
    )
    for name, low, high in (
        ("neighbour_count", 0, n_rows),
        ("neighbour_k", 1, MAX_ORIGINAL),
        ("neighbour_distance", 0, 1),
    ):
        value = getattr(ho, name)
        if value is None:
            raise _fail(f"handover {name}", "is missing")
        v = _array(f"handover {name}", value, (r, n_tasks))
        if not np.all(np.isfinite(v)) or (v != np.round(v)).any() or (v < low).any() or (v > high).any():
            raise _fail(f"handover {name}", f"must hold whole numbers in [{low}, {high:g}]")
    assert ho.neighbour_count is not None  # checked in the loop above
    if (ho.neighbour_count[kind == 1] < 1).any():
        raise _fail("handover neighbour_count", "must be at least 1 at the k-nearest-neighbour fractions")
