"""Compiled (numba) inverse kinematics of a serial arm's ``ee`` frame: the damped least-squares
solver of :class:`ipromp_pin.robot.arm_transfer.PoseSolver` (its Pinocchio version is the reference),
over whole paths in one call, and the frame's forward kinematics over many samples.

The chain (:class:`ipromp_pin.robot.arm_chain.ArmChain`): ``x0`` (n, 4, 4) each arm joint's frame in
the previous one's at zero angle (the first in the scene frame), ``axis`` (n, 3) its unit axis in its
own frame, ``ee`` (4, 4) the ``ee`` frame in the last joint's. The pose error is ``log6`` of the
remaining transform in the ``ee`` frame, its Jacobian ``Jlog6`` of the inverse transform times the
frame Jacobian (local frame): the same formulas Pinocchio evaluates (``log3`` with its Taylor
expansions near 0 and its axis recovery near pi). Imported on first use through the kernel switch
(:mod:`ipromp_pin.robot.arm_chain`), compiled on the first call and cached on disk.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}

_EPS = 2.220446049250313e-16
_PREC2 = _EPS ** (1.0 / 3.0)  # the Taylor expansions' switch of degree 2
_PREC3 = _EPS ** (1.0 / 4.0)  # and of degree 3


@njit(**_JIT)
def _chain_pose(
    q: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    rot: np.ndarray,
    pos: np.ndarray,
) -> None:
    """The ``ee`` frame's rotation ``rot`` (3, 3) and position ``pos`` (3,) at ``q`` (n,) [rad],
    with every joint's origin ``origins`` (n, 3) and world axis ``axes`` (n, 3)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px = py = pz = 0.0
    for k in range(q.size):
        x = x0[k]
        px, py, pz = (
            px + r00 * x[0, 3] + r01 * x[1, 3] + r02 * x[2, 3],
            py + r10 * x[0, 3] + r11 * x[1, 3] + r12 * x[2, 3],
            pz + r20 * x[0, 3] + r21 * x[1, 3] + r22 * x[2, 3],
        )
        a00 = r00 * x[0, 0] + r01 * x[1, 0] + r02 * x[2, 0]
        a01 = r00 * x[0, 1] + r01 * x[1, 1] + r02 * x[2, 1]
        a02 = r00 * x[0, 2] + r01 * x[1, 2] + r02 * x[2, 2]
        a10 = r10 * x[0, 0] + r11 * x[1, 0] + r12 * x[2, 0]
        a11 = r10 * x[0, 1] + r11 * x[1, 1] + r12 * x[2, 1]
        a12 = r10 * x[0, 2] + r11 * x[1, 2] + r12 * x[2, 2]
        a20 = r20 * x[0, 0] + r21 * x[1, 0] + r22 * x[2, 0]
        a21 = r20 * x[0, 1] + r21 * x[1, 1] + r22 * x[2, 1]
        a22 = r20 * x[0, 2] + r21 * x[1, 2] + r22 * x[2, 2]
        ux, uy, uz = axis[k, 0], axis[k, 1], axis[k, 2]
        origins[k, 0], origins[k, 1], origins[k, 2] = px, py, pz
        axes[k, 0] = a00 * ux + a01 * uy + a02 * uz
        axes[k, 1] = a10 * ux + a11 * uy + a12 * uz
        axes[k, 2] = a20 * ux + a21 * uy + a22 * uz
        c_, s_ = math.cos(q[k]), math.sin(q[k])
        if ux == 0.0 and uy == 0.0 and uz == 1.0:  # the usual z axis: the rotation's two columns
            r00, r01, r02 = a00 * c_ + a01 * s_, a01 * c_ - a00 * s_, a02
            r10, r11, r12 = a10 * c_ + a11 * s_, a11 * c_ - a10 * s_, a12
            r20, r21, r22 = a20 * c_ + a21 * s_, a21 * c_ - a20 * s_, a22
            continue
        t_ = 1.0 - c_
        m00, m01, m02 = c_ + t_ * ux * ux, t_ * ux * uy - s_ * uz, t_ * ux * uz + s_ * uy
        m10, m11, m12 = t_ * ux * uy + s_ * uz, c_ + t_ * uy * uy, t_ * uy * uz - s_ * ux
        m20, m21, m22 = t_ * ux * uz - s_ * uy, t_ * uy * uz + s_ * ux, c_ + t_ * uz * uz
        r00, r01, r02 = (
            a00 * m00 + a01 * m10 + a02 * m20,
            a00 * m01 + a01 * m11 + a02 * m21,
            a00 * m02 + a01 * m12 + a02 * m22,
        )
        r10, r11, r12 = (
            a10 * m00 + a11 * m10 + a12 * m20,
            a10 * m01 + a11 * m11 + a12 * m21,
            a10 * m02 + a11 * m12 + a12 * m22,
        )
        r20, r21, r22 = (
            a20 * m00 + a21 * m10 + a22 * m20,
            a20 * m01 + a21 * m11 + a22 * m21,
            a20 * m02 + a21 * m12 + a22 * m22,
        )
    pos[0] = px + r00 * ee[0, 3] + r01 * ee[1, 3] + r02 * ee[2, 3]
    pos[1] = py + r10 * ee[0, 3] + r11 * ee[1, 3] + r12 * ee[2, 3]
    pos[2] = pz + r20 * ee[0, 3] + r21 * ee[1, 3] + r22 * ee[2, 3]
    for c in range(3):
        rot[0, c] = r00 * ee[0, c] + r01 * ee[1, c] + r02 * ee[2, c]
        rot[1, c] = r10 * ee[0, c] + r11 * ee[1, c] + r12 * ee[2, c]
        rot[2, c] = r20 * ee[0, c] + r21 * ee[1, c] + r22 * ee[2, c]


@njit(**_JIT)
def chain_fk(
    q: np.ndarray, x0: np.ndarray, axis: np.ndarray, ee: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The ``ee`` frame's positions (M, 3) [m] and rotations (M, 3, 3) along ``q`` (M, n) [rad]."""
    m, n = q.shape
    pos = np.empty((m, 3))
    rot = np.empty((m, 3, 3))
    origins = np.empty((n, 3))
    axes = np.empty((n, 3))
    for i in range(m):
        _chain_pose(q[i], x0, axis, ee, origins, axes, rot[i], pos[i])
    return pos, rot


@njit(**_JIT)
def _theta_axis(i0: int, val: float, r: np.ndarray, axis: np.ndarray) -> float:
    """Angle [rad] and unit axis (3,) of a rotation near pi, from its diagonal entry ``i0``."""
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    s = math.sqrt(val + _EPS + _EPS * _EPS) * (1.0 if r[i2, i1] >= r[i1, i2] else -1.0)
    axis[i0] = s / 2.0
    axis[i1] = (r[i1, i0] + r[i0, i1]) / (2.0 * s)
    axis[i2] = (r[i2, i0] + r[i0, i2]) / (2.0 * s)
    w = (r[i2, i1] - r[i1, i2]) / (2.0 * s)
    norm = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
    axis /= norm
    return 2.0 * math.atan2(norm, w)


@njit(**_JIT)
def _log3(rot: np.ndarray, out: np.ndarray) -> float:
    """The rotation vector ``out`` (3,) of ``rot`` (3, 3) (re-orthonormalised first); returns its
    angle [rad] in [0, pi]."""
    r = np.empty((3, 3))
    n0 = math.sqrt(rot[0, 0] ** 2 + rot[1, 0] ** 2 + rot[2, 0] ** 2)
    n1 = math.sqrt(rot[0, 1] ** 2 + rot[1, 1] ** 2 + rot[2, 1] ** 2)
    for k in range(3):
        r[k, 0] = rot[k, 0] / n0
        r[k, 1] = rot[k, 1] / n1
    r[0, 2] = r[1, 0] * r[2, 1] - r[2, 0] * r[1, 1]
    r[1, 2] = r[2, 0] * r[0, 1] - r[0, 0] * r[2, 1]
    r[2, 2] = r[0, 0] * r[1, 1] - r[1, 0] * r[0, 1]
    r[0, 0] = r[1, 1] * r[2, 2] - r[2, 1] * r[1, 2]
    r[1, 0] = r[2, 1] * r[0, 2] - r[0, 1] * r[2, 2]
    r[2, 0] = r[0, 1] * r[1, 2] - r[1, 1] * r[0, 2]
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    cos_value = (tr - 1.0) / 2.0
    if cos_value < -1.0 + _PREC2:  # near pi: the axis from the diagonal
        val = np.empty(3)
        for k in range(3):
            val[k] = 2.0 * r[k, k] - tr + 1.0
        i0 = 0 if (val[0] >= val[1] and val[0] >= val[2]) else (1 if val[1] >= val[2] else 2)
        theta = _theta_axis(i0, val[i0], r, out)
        out *= theta
        return theta
    expansion = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
    theta = math.acos(cos_value) if tr <= 3.0 - _PREC2 else expansion
    a0, a1, a2 = 0.5 * (r[2, 1] - r[1, 2]), 0.5 * (r[0, 2] - r[2, 0]), 0.5 * (r[1, 0] - r[0, 1])
    if theta >= _PREC2:
        t = theta / math.sin(theta)
    else:
        sq = a0 * a0 + a1 * a1 + a2 * a2
        t = 1.0 + sq / 6.0 + sq * sq * 3.0 / 40.0
    out[0], out[1], out[2] = t * a0, t * a1, t * a2
    return theta


@njit(**_JIT)
def log6(rot: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``log6`` (6,) (linear, then angular) of the transform ``(rot, p)``."""
    w = np.empty(3)
    a0, a1, a2 = 0.5 * (rot[2, 1] - rot[1, 2]), 0.5 * (rot[0, 2] - rot[2, 0]), 0.5 * (rot[1, 0] - rot[0, 1])
    t2 = a0 * a0 + a1 * a1 + a2 * a2
    tr = rot[0, 0] + rot[1, 1] + rot[2, 2]
    theta = _log3(rot, w)
    if tr >= 3.0 - _PREC2:
        alpha = 1.0 - t2 / 12.0 - t2 * t2 / 720.0
        beta = 1.0 / 12.0 + t2 / 720.0
    else:
        st, ct = math.sin(theta), math.cos(theta)
        alpha = theta * st / (2.0 * (1.0 - ct))
        beta = 1.0 / (theta * theta) - st / (2.0 * theta * (1.0 - ct))
    wp = w[0] * p[0] + w[1] * p[1] + w[2] * p[2]
    cx = w[1] * p[2] - w[2] * p[1]
    cy = w[2] * p[0] - w[0] * p[2]
    cz = w[0] * p[1] - w[1] * p[0]
    out[0] = alpha * p[0] - 0.5 * cx + beta * wp * w[0]
    out[1] = alpha * p[1] - 0.5 * cy + beta * wp * w[1]
    out[2] = alpha * p[2] - 0.5 * cz + beta * wp * w[2]
    out[3], out[4], out[5] = w[0], w[1], w[2]


@njit(**_JIT)
def _add_half_skew(m: np.ndarray, v: np.ndarray) -> None:
    """``m <- m + [v]x / 2`` for a (3, 3) matrix and the skew-symmetric matrix of ``v`` (3,)."""
    m[0, 1] -= 0.5 * v[2]
    m[0, 2] += 0.5 * v[1]
    m[1, 0] += 0.5 * v[2]
    m[1, 2] -= 0.5 * v[0]
    m[2, 0] -= 0.5 * v[1]
    m[2, 1] += 0.5 * v[0]


@njit(**_JIT)
def jlog6(rot: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``Jlog6`` (6, 6) of the transform ``(rot, p)``: the derivative of its ``log6`` under a right
    perturbation (blocks ``[[A, C A], [0, A]]``, ``A`` the derivative of ``log3``)."""
    w = np.empty(3)
    t = _log3(rot, w)
    st, ct = math.sin(t), math.cos(t)
    st_1mct = st / (1.0 - ct)
    if t < _PREC3:
        alpha3 = 1.0 / 12.0 + t * t / 720.0
        diag = 0.5 * (2.0 - t * t / 6.0)
    else:
        alpha3 = 1.0 / (t * t) - st_1mct / (2.0 * t)
        diag = 0.5 * (t * st_1mct)
    a = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            a[r, c] = alpha3 * w[r] * w[c]
        a[r, r] += diag
    _add_half_skew(a, w)
    t2 = t * t
    inv_2_2ct = 1.0 / (2.0 * (1.0 - ct))
    if t < _PREC3:
        beta = 1.0 / 12.0 + t2 / 720.0
        beta_dot = 1.0 / 360.0
    else:
        tinv = 1.0 / t
        t2inv = tinv * tinv
        beta = t2inv - st * tinv * inv_2_2ct
        beta_dot = -2.0 * t2inv * t2inv + (1.0 + st * tinv) * t2inv * inv_2_2ct
    wp = w[0] * p[0] + w[1] * p[1] + w[2] * p[2]
    cm = np.empty((3, 3))
    for r in range(3):
        v3 = beta_dot * wp * w[r] - (t2 * beta_dot + 2.0 * beta) * p[r]
        for c in range(3):
            cm[r, c] = v3 * w[c] + beta * w[r] * p[c]
        cm[r, r] += wp * beta
    _add_half_skew(cm, p)
    out[:] = 0.0
    for r in range(3):
        for c in range(3):
            out[r, c] = a[r, c]
            out[3 + r, 3 + c] = a[r, c]
            out[r, 3 + c] = cm[r, 0] * a[0, c] + cm[r, 1] * a[1, c] + cm[r, 2] * a[2, c]


@njit(**_JIT)
def _cholesky6(a: np.ndarray, low: np.ndarray) -> None:
    """The lower Cholesky factor ``low`` (6, 6) of the symmetric positive definite ``a`` (6, 6)."""
    for j in range(6):
        d = a[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        d = math.sqrt(d)
        low[j, j] = d
        for i in range(j + 1, 6):
            v = a[i, j]
            for k in range(j):
                v -= low[i, k] * low[j, k]
            low[i, j] = v / d
        for i in range(j):
            low[i, j] = 0.0


@njit(**_JIT)
def _cho_solve6(low: np.ndarray, b: np.ndarray) -> None:
    """``b <- (low low^T)^-1 b`` for a lower Cholesky factor ``low`` (6, 6) and ``b`` (6,)."""
    for r in range(6):
        v = b[r]
        for c in range(r):
            v -= low[r, c] * b[c]
        b[r] = v / low[r, r]
    for r in range(5, -1, -1):
        v = b[r]
        for c in range(r + 1, 6):
            v -= low[c, r] * b[c]
        b[r] = v / low[r, r]


@njit(**_JIT)
def _pose_error(
    q: np.ndarray,
    rt: np.ndarray,
    pt: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    e: np.ndarray,
    jac: np.ndarray,
    work: np.ndarray,
) -> tuple[float, float]:
    """The pose error ``e`` (6,) in the ee frame toward ``(rt, pt)`` and its Jacobian ``jac`` (6, n)
    at ``q`` (n,) (``work``: (2 n + 24, 6) scratch); returns the position and orientation errors
    [m], [rad]."""
    n = q.size
    origins, axes, local = work[:n, :3], work[n : 2 * n, :3], work[2 * n : 2 * n + 6, :n]
    jl = work[2 * n + 6 : 2 * n + 12]
    rc, rr, ri = (
        work[2 * n + 12 : 2 * n + 15, :3],
        work[2 * n + 15 : 2 * n + 18, :3],
        work[2 * n + 18 : 2 * n + 21, :3],
    )
    pc, pr, pi = work[2 * n + 21, :3], work[2 * n + 22, :3], work[2 * n + 23, :3]
    _chain_pose(q, x0, axis, ee, origins, axes, rc, pc)
    for r in range(3):  # the remaining transform: current^-1 target
        pr[r] = rc[0, r] * (pt[0] - pc[0]) + rc[1, r] * (pt[1] - pc[1]) + rc[2, r] * (pt[2] - pc[2])
        for c in range(3):
            rr[r, c] = rc[0, r] * rt[0, c] + rc[1, r] * rt[1, c] + rc[2, r] * rt[2, c]
    log6(rr, pr, e)
    for r in range(3):  # its inverse
        for c in range(3):
            ri[r, c] = rr[c, r]
    for r in range(3):
        pi[r] = -(ri[r, 0] * pr[0] + ri[r, 1] * pr[1] + ri[r, 2] * pr[2])
    jlog6(ri, pi, jl)
    for k in range(n):  # the frame Jacobian in the ee frame: linear, then angular
        dx, dy, dz = pc[0] - origins[k, 0], pc[1] - origins[k, 1], pc[2] - origins[k, 2]
        zx, zy, zz = axes[k, 0], axes[k, 1], axes[k, 2]
        vx, vy, vz = zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx
        for r in range(3):
            local[r, k] = rc[0, r] * vx + rc[1, r] * vy + rc[2, r] * vz
            local[3 + r, k] = rc[0, r] * zx + rc[1, r] * zy + rc[2, r] * zz
    for r in range(6):
        for k in range(n):
            acc = 0.0
            for c in range(6):
                acc += jl[r, c] * local[c, k]
            jac[r, k] = acc
    err_p = math.sqrt(pr[0] * pr[0] + pr[1] * pr[1] + pr[2] * pr[2])
    err_r = math.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5])
    return err_p, err_r


@njit(**_JIT)
def _solve(
    rt: np.ndarray,
    pt: np.ndarray,
    seed: np.ndarray,
    max_iter: int,
    limits: np.ndarray,
    params: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    q_out: np.ndarray,
    jac: np.ndarray,
) -> tuple[float, float]:
    """One pose from ``seed`` (n,): :meth:`PoseSolver.solve`'s iterations. ``limits`` (4, n): lower,
    upper, middle, null-space weight; ``params``: damping, position and orientation tolerances [m],
    [rad] (where iterating stops), null-space gain, largest step [rad]. Writes ``q_out`` (n,) and
    ``jac`` (6, n); returns the position and orientation errors [m], [rad] of the last evaluation.
    The damped pseudo-inverse ``J^T (J J^T + damping I)^-1`` is applied through a Cholesky factor."""
    n = seed.size
    lo, hi, mid, pull = limits[0], limits[1], limits[2], limits[3]
    damping, tol_m, tol_r, gain, max_step = params[0], params[1], params[2], params[3], params[4]
    work = np.empty((2 * n + 24, max(n, 6)))
    a, low = np.empty((6, 6)), np.empty((6, 6))
    e, u = np.empty(6), np.empty(6)
    step, z = np.empty(n), np.empty(n)
    q = q_out
    for j in range(n):
        q[j] = min(max(seed[j], lo[j]), hi[j])
    err_p = err_r = np.inf
    jac[:] = 0.0
    for k in range(max_iter):
        err_p, err_r = _pose_error(q, rt, pt, x0, axis, ee, e, jac, work)
        if err_p <= tol_m and err_r <= tol_r:
            break
        for r in range(6):
            for c in range(r + 1):
                acc = 0.0
                for j in range(n):
                    acc += jac[r, j] * jac[c, j]
                a[r, c] = a[c, r] = acc
            a[r, r] += damping
        _cholesky6(a, low)
        _cho_solve6(low, e)
        for j in range(n):
            acc = 0.0
            for r in range(6):
                acc += jac[r, j] * e[r]
            step[j] = acc
        if k == 0:  # spare freedom: toward the middle of the limits, in the pose task's null space
            for j in range(n):
                z[j] = gain * pull[j] * (mid[j] - q[j])
            for r in range(6):
                acc = 0.0
                for j in range(n):
                    acc += jac[r, j] * z[j]
                u[r] = acc
            _cho_solve6(low, u)
            for j in range(n):
                acc = 0.0
                for r in range(6):
                    acc += jac[r, j] * u[r]
                step[j] += z[j] - acc
        largest = 0.0
        for j in range(n):
            largest = max(largest, abs(step[j]))
        scale = max_step / largest if largest > max_step else 1.0
        for j in range(n):
            q[j] = min(max(q[j] + step[j] * scale, lo[j]), hi[j])
    return err_p, err_r


@njit(**_JIT)
def solve_sequence(
    rot: np.ndarray,
    pos: np.ndarray,
    order: np.ndarray,
    seed_from: np.ndarray,
    seeds: np.ndarray,
    max_iters: np.ndarray,
    limits: np.ndarray,
    params: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    q: np.ndarray,
    err: np.ndarray,
    jacs: np.ndarray,
) -> int:
    """Solve the poses ``(rot[i], pos[i])`` (M, 3, 3), (M, 3) for ``i = order[t]`` in turn, each from
    the solution of pose ``seed_from[t]`` (solved earlier) or, where that is negative, from
    ``seeds[t]`` (T, n), with at most ``max_iters[t]`` iterations: into ``q`` (M, n), ``err``
    (M, 2) (position [m], orientation [rad]) and ``jacs`` (M, 6, n); returns the poses solved."""
    for t in range(order.size):
        i = order[t]
        seed = q[seed_from[t]].copy() if seed_from[t] >= 0 else seeds[t]
        ep, er = _solve(rot[i], pos[i], seed, max_iters[t], limits, params, x0, axis, ee, q[i], jacs[i])
        err[i, 0] = ep
        err[i, 1] = er
    return order.size


@njit(**_JIT)
def solve_first(
    rot: np.ndarray,
    pos: np.ndarray,
    seeds: np.ndarray,
    max_iter: int,
    limits: np.ndarray,
    params: np.ndarray,
    reach: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    q: np.ndarray,
    jac: np.ndarray,
) -> tuple[float, float]:
    """One pose ``(rot, pos)`` from no previous solution: :meth:`PoseSolver.first` over ``seeds``
    (S, n) in turn (``reach``: the position and orientation tolerances of a reached pose [m], [rad]
    and the margin that ends the search): the first reached solution that far from every limit, else
    the reached one with the largest margin, else the one closest to the pose. Writes ``q`` (n,),
    ``jac`` (6, n); returns its errors [m], [rad]."""
    n = seeds.shape[1]
    lo, hi = limits[0], limits[1]
    qs = np.empty(n)
    js = np.empty((6, n))
    best_ok, best_key = False, -np.inf
    best_p = best_r = np.inf
    found = False
    for s in range(seeds.shape[0]):
        ep, er = _solve(rot, pos, seeds[s], max_iter, limits, params, x0, axis, ee, qs, js)
        ok = ep <= reach[0] and er <= reach[1]
        if ok:
            key = np.inf
            for j in range(n):
                key = min(key, min(qs[j] - lo[j], hi[j] - qs[j]) / (hi[j] - lo[j]))
        else:
            key = -(ep + 0.1 * er)
        if not found or (ok and not best_ok) or (ok == best_ok and key > best_key):
            found, best_ok, best_key, best_p, best_r = True, ok, key, ep, er
            q[:] = qs
            jac[:] = js
        if ok and key >= reach[2]:
            break
    return best_p, best_r


@njit(**_JIT)
def linearised_samples(
    q_samples: np.ndarray,
    x0: np.ndarray,
    axis: np.ndarray,
    ee: np.ndarray,
    pos_mean: np.ndarray,
    rot_mean: np.ndarray,
    jacs: np.ndarray,
    q_mean: np.ndarray,
    damping: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled source paths ``q_samples`` (S, M, n_source) [rad] as target paths (S, M, n) by one
    damped least-squares step around the target's mean path ``q_mean`` (M, n) with its Jacobians
    ``jacs`` (M, 6, n): each sample's gripper pose (the source chain ``x0``, ``axis``, ``ee``) in the
    mean's gripper frame (``pos_mean`` (M, 3), ``rot_mean`` (M, 3, 3)) as translation and rotation
    vector. Returns the paths and the samples' last gripper poses (S, 3), (S, 3, 3)."""
    s_n, m, ns = q_samples.shape
    n = q_mean.shape[1]
    out = np.empty((s_n, m, n))
    end_pos = np.empty((s_n, 3))
    end_rot = np.empty((s_n, 3, 3))
    origins = np.empty((ns, 3))
    axes = np.empty((ns, 3))
    rot = np.empty((3, 3))
    pos = np.empty(3)
    rel = np.empty((3, 3))
    e = np.empty(6)
    w = np.empty(3)
    a, low = np.empty((6, 6)), np.empty((6, 6))
    for i in range(m):
        for r in range(6):
            for c in range(r + 1):
                acc = 0.0
                for j in range(n):
                    acc += jacs[i, r, j] * jacs[i, c, j]
                a[r, c] = a[c, r] = acc
            a[r, r] += damping
        _cholesky6(a, low)
        for s in range(s_n):
            _chain_pose(q_samples[s, i], x0, axis, ee, origins, axes, rot, pos)
            if i == m - 1:
                end_pos[s] = pos
                end_rot[s] = rot
            rm = rot_mean[i]
            for r in range(3):
                e[r] = (
                    rm[0, r] * (pos[0] - pos_mean[i, 0])
                    + rm[1, r] * (pos[1] - pos_mean[i, 1])
                    + rm[2, r] * (pos[2] - pos_mean[i, 2])
                )
                for c in range(3):
                    rel[r, c] = rm[0, r] * rot[0, c] + rm[1, r] * rot[1, c] + rm[2, r] * rot[2, c]
            _log3(rel, w)
            e[3], e[4], e[5] = w[0], w[1], w[2]
            _cho_solve6(low, e)  # (J J^T + damping) x = e
            for j in range(n):
                acc = q_mean[i, j]
                for r in range(6):
                    acc += jacs[i, r, j] * e[r]
                out[s, i, j] = acc
    return out, end_pos, end_rot
