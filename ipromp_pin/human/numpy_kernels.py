"""The human checks' kernels in plain numpy: what a process runs while the numba ones are not compiled.

Same functions, arguments, results and shapes as :mod:`ipromp_pin.human.separation_kernels`, written
as batched numpy operations over all samples and pairs (loops only over the arm's joints): the same
arithmetic up to the order of summation, so results agree to rounding (the tests hold both to 1e-9).
Nothing to compile; the kernel switch (:func:`ipromp_pin.promp.compiled.kernels`) chooses between them.
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-12


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _rodrigues(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) about the unit ``axis`` (3,) by ``angle`` (N,) [rad]."""
    x, y, z = axis
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    out = np.empty((angle.size, 3, 3))
    out[:, 0, 0] = c + t * x * x
    out[:, 0, 1] = t * x * y - s * z
    out[:, 0, 2] = t * x * z + s * y
    out[:, 1, 0] = t * x * y + s * z
    out[:, 1, 1] = c + t * y * y
    out[:, 1, 2] = t * y * z - s * x
    out[:, 2, 0] = t * x * z - s * y
    out[:, 2, 1] = t * y * z + s * x
    out[:, 2, 2] = c + t * z * z
    return out


def arm_frames(
    q: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    anchor: np.ndarray,
    a_local: np.ndarray,
    b_local: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Joint origins, world joint axes (N, J, 3) and capsule end points (N, L, 3) along ``q`` (N, J)
    (``x0`` (J, 4, 4): previous joint frame -> joint frame at zero angle; ``axis`` (J, 3) local)."""
    n, nj = q.shape
    origins = np.empty((n, nj, 3))
    axes = np.empty((n, nj, 3))
    rots = np.empty((n, nj, 3, 3))
    pos = np.zeros((n, 3))
    rot = np.broadcast_to(np.eye(3), (n, 3, 3))
    for k in range(nj):
        pos = pos + rot @ x0[k, :3, 3]
        rot = rot @ x0[k, :3, :3]
        origins[:, k] = pos
        axes[:, k] = rot @ axis[k]
        rot = rot @ _rodrigues(axis[k], q[:, k])
        rots[:, k] = rot
    anchor = np.asarray(anchor, dtype=np.int64)
    held = rots[:, anchor]  # (N, L, 3, 3)
    ca = origins[:, anchor] + np.einsum("nlrc,lc->nlr", held, a_local)
    cb = origins[:, anchor] + np.einsum("nlrc,lc->nlr", held, b_local)
    return origins, axes, ca, cb


def _closest(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters (s, t) in [0, 1] of the closest points of segments ``p1 + s d1`` and ``p2 + t d2``
    (arrays broadcasting to (..., 3)), with the branches of the compiled kernel's ``_closest``."""
    r = p1 - p2
    a, e = _dot(d1, d1), _dot(d2, d2)
    f, c, b = _dot(d2, r), _dot(d1, r), _dot(d1, d2)
    a, e, f, c, b = np.broadcast_arrays(a, e, f, c, b)
    a_ok, e_ok = a > _EPS, e > _EPS
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    proper = denom > _EPS * a * e
    s = np.where(proper, np.clip((b * f - c * e) / np.where(proper, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_s
    below, above = t < 0.0, t > 1.0
    s = np.where(below, np.clip(-c / a_s, 0.0, 1.0), np.where(above, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments (points)
    s = np.where(e_ok, s, np.clip(-c / a_s, 0.0, 1.0))
    t = np.where(e_ok, t, 0.0)
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.where(e_ok, np.clip(f / e_s, 0.0, 1.0), 0.0))
    return s, t


def capsule_distances(
    ra: np.ndarray, rb: np.ndarray, rr: np.ndarray, ha: np.ndarray, hb: np.ndarray, hr: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distances (N, L, P) [m] between robot capsules (``ra``, ``rb`` (N, L, 3), radii ``rr`` (L,))
    and body capsules (``ha``, ``hb`` (N, P, 3), radii ``hr`` (N, P)), negative when they overlap,
    and the closest points of their axes (N, L, P, 3) on the robot and on the body."""
    p1, d1 = ra[:, :, None, :], (rb - ra)[:, :, None, :]
    p2, d2 = ha[:, None, :, :], (hb - ha)[:, None, :, :]
    s, t = _closest(p1, d1, p2, d2)
    cr = p1 + s[..., None] * d1
    ch = p2 + t[..., None] * d2
    gap = cr - ch
    dist = np.sqrt(_dot(gap, gap)) - rr[None, :, None] - hr[:, None, :]
    return dist, cr, ch


def approach_speeds(
    dist: np.ndarray,
    cr: np.ndarray,
    ch: np.ndarray,
    rr: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    qd: np.ndarray,
    anchor: np.ndarray,
    sp_const: float,
    sp_per_speed: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair (N, L, P): the approach speed [m/s] of the robot's closest surface point toward the
    body, S_p = ``sp_const + max(v, 0) sp_per_speed`` [m], and the unit direction (N, L, P, 3) (NaN
    where the axes meet); see :func:`ipromp_pin.human.separation_kernels.approach_speeds`."""
    omega = np.cumsum(qd[..., None] * axes, axis=1)  # (N, J, 3) angular velocity of joint k's body
    v_o = np.zeros_like(origins)  # velocity of joint k's origin
    if origins.shape[1] > 1:
        steps = np.cross(omega[:, :-1], np.diff(origins, axis=1))
        v_o[:, 1:] = np.cumsum(steps, axis=1)
    anchor = np.asarray(anchor, dtype=np.int64)
    u = ch - cr
    norm = np.sqrt(_dot(u, u))
    met = norm <= 1e-9
    u = np.where(met[..., None], 0.0, u / np.where(met, 1.0, norm)[..., None])
    lever = cr + rr[None, :, None, None] * u - origins[:, anchor][:, :, None, :]
    v = v_o[:, anchor][:, :, None, :] + np.cross(omega[:, anchor][:, :, None, :], lever)
    app = np.where(met, np.sqrt(_dot(v, v)), _dot(v, u))
    sp = sp_const + np.maximum(app, 0.0) * sp_per_speed
    unit = np.where(met[..., None], np.nan, u)
    return app, sp, unit


def inverse_effective_masses(mass: np.ndarray, sample: np.ndarray, jtu: np.ndarray) -> np.ndarray:
    """``u^T J M^-1 J^T u`` [1/kg] per pair: ``mass`` (S, n, n) the arm's inertia at S samples,
    ``sample`` (K,) which one each pair uses, ``jtu`` (K, n) its ``J^T u`` (``|L^-1 J^T u|^2`` with
    one Cholesky factorisation per sample)."""
    if jtu.shape[0] == 0:
        return np.empty(0)
    lowers = np.linalg.cholesky(mass)
    y = np.linalg.solve(lowers[sample], jtu[..., None])[..., 0]
    return np.sum(y * y, axis=1)


def pair_jtu(
    n_i: np.ndarray,
    l_i: np.ndarray,
    p_i: np.ndarray,
    cr: np.ndarray,
    unit: np.ndarray,
    rr: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    anchor: np.ndarray,
    qd: np.ndarray,
) -> np.ndarray:
    """``J^T u`` (K, n_joints) of the robot's closest surface point of each pair ``(n_i, l_i, p_i)``
    (K,): column j is ``z_j . ((x - o_j) x u)`` for the joints j that move the point. Where the axes
    meet (``unit`` NaN) ``u`` is the direction of the point's own velocity (a zero row if it rests)."""
    nj = origins.shape[1]
    u = unit[n_i, l_i, p_i]  # (K, 3)
    met = np.isnan(u[:, 0])
    u = np.where(met[:, None], 0.0, u)
    x = cr[n_i, l_i, p_i] + rr[l_i][:, None] * u
    lever = x[:, None, :] - origins[n_i]  # (K, J, 3)
    z = axes[n_i]
    moves = np.arange(nj)[None, :] <= np.asarray(anchor)[l_i][:, None]  # (K, J)
    v = np.einsum("kjc,kj->kc", np.cross(z, lever), qd[n_i] * moves)
    v_norm = np.sqrt(_dot(v, v))
    rests = met & (v_norm <= 1e-12)
    u = np.where(met[:, None], v / np.where(v_norm <= 1e-12, 1.0, v_norm)[:, None], u)
    out = _dot(z, np.cross(lever, u[:, None, :])) * moves
    out[rests] = 0.0
    return out


def separation_summary(
    ra: np.ndarray,
    rb: np.ndarray,
    rr: np.ndarray,
    ha: np.ndarray,
    hb: np.ndarray,
    hr: np.ndarray,
    body_r: np.ndarray,
    nominal: np.ndarray,
    floor: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    qd: np.ndarray,
    anchor: np.ndarray,
    sp_const: float,
    sp_per_speed: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the human checks judge of the separation (see
    :func:`ipromp_pin.human.separation_kernels.separation_summary`), from every pair's numbers."""
    dist, cr, ch = capsule_distances(ra, rb, rr, ha, hb, hr)
    app, sp, unit = approach_speeds(dist, cr, ch, rr, origins, axes, qd, anchor, sp_const, sp_per_speed)
    keep = np.asarray(nominal, dtype=bool)
    if keep.any():
        clear = (dist[:, :, keep].min(axis=1) + (hr - body_r[None, :])[:, keep]).min(axis=1)
    else:
        clear = np.full(dist.shape[0], np.inf)
    inside = dist < sp
    need = inside & (app > floor[None, None, :])
    n_i, l_i, p_i = np.nonzero(need)
    jtu = pair_jtu(n_i, l_i, p_i, cr, unit, rr, origins, axes, anchor, qd)
    within = np.asarray(inside.any(axis=(1, 2)), dtype=bool)
    return clear, within, n_i, l_i, p_i, app[need], sp[need], jtu
