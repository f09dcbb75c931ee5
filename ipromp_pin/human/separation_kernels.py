"""Compiled (numba) loops of the human checks: the capsule-capsule distances between the robot and
the body, the approach speeds, and with them (from :mod:`.chain_kernels`) the arm's forward
kinematics over many samples and its inertia. Imported on first use (importing
:mod:`ipromp_pin.human` does not import numba); compiled on the first call and cached on disk.

:func:`separation_summary` computes every number as :func:`capsule_distances`,
:func:`approach_speeds` and :func:`pair_jtu` do, and skips a pair only where bounds prove that it
cannot matter: the distance is at least the bounding spheres' (``|c_l - c_p| - R_l - R_p``), and the
speed of any surface point of a robot capsule is at most ``max(|v(a)|, |v(b)|) + r |w|`` (the
velocity field of a rigid body is affine in the point), so a pair farther than the S_p of that speed
is outside S_p, and a pair of a capsule slower than the part's ``floor`` never needs its ratio. The
same bounds over a block of samples settle most pairs for the whole block at once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .chain_kernels import arm_frames, chain_mass_matrices, inverse_effective_masses

__all__ = [
    "BLOCK",
    "approach_speeds",
    "arm_frames",
    "capsule_distances",
    "chain_mass_matrices",
    "inverse_effective_masses",
    "pair_jtu",
    "separation_summary",
]

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}
_SLACK = 1e-9
"""Margin [m], [m/s] of the separation summary's bounds: far above the rounding of their sums (1e-15
at metre scale)."""


@njit(**_JIT, inline="always")
def _closest(
    p1x: float,
    p1y: float,
    p1z: float,
    d1x: float,
    d1y: float,
    d1z: float,
    p2x: float,
    p2y: float,
    p2z: float,
    d2x: float,
    d2y: float,
    d2z: float,
) -> tuple[float, float]:
    """Parameters (s, t) in [0, 1] of the closest points of segments ``p1 + s d1`` and ``p2 + t d2``."""
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-12
    if a <= eps and e <= eps:
        return 0.0, 0.0
    if a <= eps:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = d1x * rx + d1y * ry + d1z * rz
    if e <= eps:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denom = a * e - b * b
    s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > eps * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((b - c) / a, 0.0), 1.0)
    return s, t


@njit(**_JIT)
def capsule_distances(
    ra: np.ndarray, rb: np.ndarray, rr: np.ndarray, ha: np.ndarray, hb: np.ndarray, hr: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distances (N, L, P) [m] between robot capsules (``ra``, ``rb`` (N, L, 3), radii ``rr`` (L,))
    and body capsules (``ha``, ``hb`` (N, P, 3), radii ``hr`` (N, P)), negative when they overlap,
    and the closest points of their axes (N, L, P, 3) on the robot and on the body."""
    n, nl = ra.shape[0], ra.shape[1]
    npart = ha.shape[1]
    dist = np.empty((n, nl, npart))
    cr = np.empty((n, nl, npart, 3))
    ch = np.empty((n, nl, npart, 3))
    for i in range(n):
        for m in range(nl):
            p1x, p1y, p1z = ra[i, m, 0], ra[i, m, 1], ra[i, m, 2]
            d1x, d1y, d1z = rb[i, m, 0] - p1x, rb[i, m, 1] - p1y, rb[i, m, 2] - p1z
            for p in range(npart):
                p2x, p2y, p2z = ha[i, p, 0], ha[i, p, 1], ha[i, p, 2]
                d2x, d2y, d2z = hb[i, p, 0] - p2x, hb[i, p, 1] - p2y, hb[i, p, 2] - p2z
                s, t = _closest(p1x, p1y, p1z, d1x, d1y, d1z, p2x, p2y, p2z, d2x, d2y, d2z)
                x0, x1, x2 = p1x + s * d1x, p1y + s * d1y, p1z + s * d1z
                y0, y1, y2 = p2x + t * d2x, p2y + t * d2y, p2z + t * d2z
                cr[i, m, p, 0], cr[i, m, p, 1], cr[i, m, p, 2] = x0, x1, x2
                ch[i, m, p, 0], ch[i, m, p, 1], ch[i, m, p, 2] = y0, y1, y2
                dist[i, m, p] = math.sqrt((x0 - y0) ** 2 + (x1 - y1) ** 2 + (x2 - y2) ** 2) - rr[m] - hr[i, p]
    return dist, cr, ch


@njit(**_JIT)
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
    body (its velocity ``sum_{i<=k} qd_i z_i x (x - o_i)`` projected on the unit separation direction;
    its speed where the axes meet), S_p = ``sp_const + max(v, 0) sp_per_speed`` [m], and the unit
    direction (N, L, P, 3) (NaN where the axes meet). The point velocity is the rigid-body field of
    its joint's body, ``v(o_k) + w_k x (x - o_k)``, both accumulated along the chain once per sample."""
    n, nl, npart = dist.shape
    nj = origins.shape[1]
    app = np.empty((n, nl, npart))
    sp = np.empty((n, nl, npart))
    unit = np.empty((n, nl, npart, 3))
    omega = np.empty((nj, 3))  # angular velocity of joint k's body
    v_o = np.empty((nj, 3))  # velocity of joint k's origin
    for i in range(n):
        _chain_velocities(i, origins, axes, qd, omega, v_o)
        for m in range(nl):
            k = anchor[m]
            for p in range(npart):
                x = (cr[i, m, p, 0], cr[i, m, p, 1], cr[i, m, p, 2])
                y = (ch[i, m, p, 0], ch[i, m, p, 1], ch[i, m, p, 2])
                v, ux, uy, uz, met = _surface_approach(i, k, x, y, rr[m], origins, omega, v_o)
                app[i, m, p] = v
                sp[i, m, p] = sp_const + max(v, 0.0) * sp_per_speed
                if met:
                    unit[i, m, p, 0] = unit[i, m, p, 1] = unit[i, m, p, 2] = np.nan
                else:
                    unit[i, m, p, 0], unit[i, m, p, 1], unit[i, m, p, 2] = ux, uy, uz
    return app, sp, unit


@njit(**_JIT)
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
    meet (``unit`` NaN) ``u`` is the direction of the point's own velocity."""
    k_pairs = n_i.size
    nj = origins.shape[1]
    out = np.zeros((k_pairs, nj))
    for k in range(k_pairs):
        i, m, p = n_i[k], l_i[k], p_i[k]
        ux, uy, uz = unit[i, m, p, 0], unit[i, m, p, 1], unit[i, m, p, 2]
        met = np.isnan(ux)
        if met:
            ux = uy = uz = 0.0
        x0 = cr[i, m, p, 0] + rr[m] * ux
        x1 = cr[i, m, p, 1] + rr[m] * uy
        x2 = cr[i, m, p, 2] + rr[m] * uz
        top = anchor[m]
        if met:  # the velocity's direction
            vx = vy = vz = 0.0
            for j in range(top + 1):
                lx, ly, lz = x0 - origins[i, j, 0], x1 - origins[i, j, 1], x2 - origins[i, j, 2]
                ax, ay, az = axes[i, j, 0], axes[i, j, 1], axes[i, j, 2]
                vx += qd[i, j] * (ay * lz - az * ly)
                vy += qd[i, j] * (az * lx - ax * lz)
                vz += qd[i, j] * (ax * ly - ay * lx)
            norm = math.sqrt(vx * vx + vy * vy + vz * vz)
            if norm <= 1e-12:
                continue
            ux, uy, uz = vx / norm, vy / norm, vz / norm
        for j in range(top + 1):
            lx, ly, lz = x0 - origins[i, j, 0], x1 - origins[i, j, 1], x2 - origins[i, j, 2]
            # (x - o_j) x u
            cx = ly * uz - lz * uy
            cy = lz * ux - lx * uz
            cz = lx * uy - ly * ux
            out[k, j] = axes[i, j, 0] * cx + axes[i, j, 1] * cy + axes[i, j, 2] * cz
    return out


@njit(**_JIT)
def _grow_pairs(
    n_i: np.ndarray, l_i: np.ndarray, p_i: np.ndarray, app: np.ndarray, sp: np.ndarray, jtu: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pair buffers of :func:`separation_summary`, twice as long (the first rows copied)."""
    k = n_i.size
    out = (
        np.empty(2 * k, np.int64),
        np.empty(2 * k, np.int64),
        np.empty(2 * k, np.int64),
        np.empty(2 * k),
        np.empty(2 * k),
        np.empty((2 * k, jtu.shape[1])),
    )
    out[0][:k] = n_i
    out[1][:k] = l_i
    out[2][:k] = p_i
    out[3][:k] = app
    out[4][:k] = sp
    out[5][:k] = jtu
    return out


@njit(**_JIT, inline="always")
def _approach_bound(
    end_v: np.ndarray, m: int, gx: float, gy: float, gz: float, g2: float, halves: float
) -> float:
    """An upper bound [m/s] of the approach speed of capsule ``m`` toward a body part whose centre
    is ``-g`` from the capsule's (``g2 = |g|^2``), their axes' half-lengths summing to ``halves``:
    the approach is ``v(x) . u`` with ``x`` on the capsule's axis (the surface offset adds nothing
    along ``u``), ``v`` affine along the axis (largest at an end), and ``u`` the direction between
    points of the two axes, within ``asin(halves / |g|)`` of ``-g``. Infinite where the cone is not
    narrower than a half-space (the axes may meet)."""
    dist = math.sqrt(g2)
    if not dist > halves * (1.0 + 1e-9) + 1e-9:
        return np.inf
    sin_t = halves / dist
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    ux, uy, uz = -gx / dist, -gy / dist, -gz / dist
    top = 0.0
    for end in range(2):
        vx, vy, vz = end_v[m, end, 0], end_v[m, end, 1], end_v[m, end, 2]
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        if speed <= 0.0:
            continue
        cos_p = min(max((vx * ux + vy * uy + vz * uz) / speed, -1.0), 1.0)
        if cos_p >= cos_t:
            along = speed
        else:
            along = speed * (cos_p * cos_t + math.sqrt(1.0 - cos_p * cos_p) * sin_t)
        top = max(top, along)
    return top * (1.0 + 1e-9) + 1e-9


@njit(**_JIT)
def _chain_velocities(
    i: int, origins: np.ndarray, axes: np.ndarray, qd: np.ndarray, omega: np.ndarray, v_o: np.ndarray
) -> None:
    """Fill ``omega`` (n_joints, 3) [rad/s] with each joint's body angular velocity and ``v_o``
    (n_joints, 3) [m/s] with the velocity of each joint's origin at sample ``i``."""
    wx = wy = wz = 0.0
    for k in range(origins.shape[1]):
        # v(o_k) = sum_{j<k} qd_j z_j x (o_k - o_j) = v(o_{k-1}) + w_{k-1} x (o_k - o_{k-1})
        if k == 0:
            v_o[0, 0] = v_o[0, 1] = v_o[0, 2] = 0.0
        else:
            lx = origins[i, k, 0] - origins[i, k - 1, 0]
            ly = origins[i, k, 1] - origins[i, k - 1, 1]
            lz = origins[i, k, 2] - origins[i, k - 1, 2]
            v_o[k, 0] = v_o[k - 1, 0] + wy * lz - wz * ly
            v_o[k, 1] = v_o[k - 1, 1] + wz * lx - wx * lz
            v_o[k, 2] = v_o[k - 1, 2] + wx * ly - wy * lx
        wx += qd[i, k] * axes[i, k, 0]
        wy += qd[i, k] * axes[i, k, 1]
        wz += qd[i, k] * axes[i, k, 2]
        omega[k, 0], omega[k, 1], omega[k, 2] = wx, wy, wz


@njit(**_JIT)
def _capsule_speed_bounds(
    i: int,
    ra: np.ndarray,
    rb: np.ndarray,
    rr: np.ndarray,
    anchor: np.ndarray,
    origins: np.ndarray,
    omega: np.ndarray,
    v_o: np.ndarray,
    sp_const: float,
    sp_per_speed: float,
    end_v: np.ndarray,
    v_bound: np.ndarray,
    sp_bound: np.ndarray,
) -> None:
    """Per robot capsule at sample ``i``: its end points' velocities ``end_v`` (L, 2, 3) [m/s], the
    largest speed of any of its surface points ``v_bound`` (L,) [m/s] and that speed's S_p
    ``sp_bound`` (L,) [m]."""
    slack = _SLACK
    for m in range(ra.shape[1]):
        k = anchor[m]
        ax, ay, az = omega[k, 0], omega[k, 1], omega[k, 2]
        top = 0.0
        for end in range(2):
            e = ra if end == 0 else rb
            lx = e[i, m, 0] - origins[i, k, 0]
            ly = e[i, m, 1] - origins[i, k, 1]
            lz = e[i, m, 2] - origins[i, k, 2]
            vx = v_o[k, 0] + ay * lz - az * ly
            vy = v_o[k, 1] + az * lx - ax * lz
            vz = v_o[k, 2] + ax * ly - ay * lx
            top = max(top, math.sqrt(vx * vx + vy * vy + vz * vz))
            end_v[m, end, 0], end_v[m, end, 1], end_v[m, end, 2] = vx, vy, vz
        v = top + rr[m] * math.sqrt(ax * ax + ay * ay + az * az) + slack
        v_bound[m] = v
        sp_bound[m] = sp_const + v * sp_per_speed + slack


@njit(**_JIT)
def _part_spheres(
    i: int,
    ha: np.ndarray,
    hb: np.ndarray,
    hr: np.ndarray,
    body_r: np.ndarray,
    nominal: np.ndarray,
    out: np.ndarray,
) -> None:
    """Per body part at sample ``i``, into the rows of ``out`` (7, P): its bounding sphere's centre
    (rows 0-2) [m], the half length of its axis (3) and its reach, half length + radius (4) [m], its
    inflation (5) [m], and how far past a robot capsule's bounding sphere its nominal clearance can
    reach (6) [m] (``-inf`` for parts that do not count toward the clearance)."""
    slack = _SLACK
    for p in range(ha.shape[1]):
        d2x, d2y, d2z = hb[i, p, 0] - ha[i, p, 0], hb[i, p, 1] - ha[i, p, 1], hb[i, p, 2] - ha[i, p, 2]
        out[0, p] = ha[i, p, 0] + 0.5 * d2x
        out[1, p] = ha[i, p, 1] + 0.5 * d2y
        out[2, p] = ha[i, p, 2] + 0.5 * d2z
        out[3, p] = 0.5 * math.sqrt(d2x * d2x + d2y * d2y + d2z * d2z)
        out[4, p] = out[3, p] + hr[i, p] + slack
        out[5, p] = hr[i, p] - body_r[p]
        # the nominal clearance is at least |g| - R_l - reach + infl: how far past R_l it can be
        out[6, p] = out[4, p] - out[5, p] + slack if nominal[p] else -np.inf


@njit(**_JIT, inline="always")
def _surface_approach(
    i: int,
    k: int,
    x: tuple[float, float, float],
    y: tuple[float, float, float],
    r: float,
    origins: np.ndarray,
    omega: np.ndarray,
    v_o: np.ndarray,
) -> tuple[float, float, float, float, bool]:
    """The approach speed [m/s] of the robot capsule of radius ``r`` [m] on joint ``k`` toward a body
    part at sample ``i``, from the closest points of their axes ``x`` and ``y`` [m], as
    :func:`approach_speeds` computes it, and the unit direction ``u`` toward the part with whether
    the two touch (then ``u`` is 0 and the speed is the surface point's whole speed)."""
    ux, uy, uz = y[0] - x[0], y[1] - x[1], y[2] - x[2]
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    met = norm <= 1e-9
    if not met:
        ux, uy, uz = ux / norm, uy / norm, uz / norm
    else:
        ux, uy, uz = 0.0, 0.0, 0.0
    lx = x[0] + r * ux - origins[i, k, 0]
    ly = x[1] + r * uy - origins[i, k, 1]
    lz = x[2] + r * uz - origins[i, k, 2]
    ax, ay, az = omega[k, 0], omega[k, 1], omega[k, 2]
    vx = v_o[k, 0] + ay * lz - az * ly
    vy = v_o[k, 1] + az * lx - ax * lz
    vz = v_o[k, 2] + ax * ly - ay * lx
    v = math.sqrt(vx * vx + vy * vy + vz * vz) if met else vx * ux + vy * uy + vz * uz
    return v, ux, uy, uz, met


@njit(**_JIT)
def _surface_jtu(
    i: int,
    k: int,
    xs: tuple[float, float, float],
    ux: float,
    uy: float,
    uz: float,
    met: bool,
    origins: np.ndarray,
    axes: np.ndarray,
    qd: np.ndarray,
    out: np.ndarray,
) -> None:
    """``J^T u`` (n_joints,) of the surface point ``xs`` [m] of a capsule on joint ``k`` at sample
    ``i`` into ``out``, as :func:`pair_jtu` computes it (``met``: the pair touches, so ``u`` is the
    point's direction of motion; zero when it does not move)."""
    if met:
        wvx = wvy = wvz = 0.0
        for j in range(k + 1):
            qx = xs[0] - origins[i, j, 0]
            qy = xs[1] - origins[i, j, 1]
            qz = xs[2] - origins[i, j, 2]
            zx, zy, zz = axes[i, j, 0], axes[i, j, 1], axes[i, j, 2]
            wvx += qd[i, j] * (zy * qz - zz * qy)
            wvy += qd[i, j] * (zz * qx - zx * qz)
            wvz += qd[i, j] * (zx * qy - zy * qx)
        wn = math.sqrt(wvx * wvx + wvy * wvy + wvz * wvz)
        out[:] = 0.0
        if wn <= 1e-12:
            return
        ux, uy, uz = wvx / wn, wvy / wn, wvz / wn
    for j in range(out.shape[0]):
        if j > k:
            out[j] = 0.0
            continue
        qx = xs[0] - origins[i, j, 0]
        qy = xs[1] - origins[i, j, 1]
        qz = xs[2] - origins[i, j, 2]
        ex = qy * uz - qz * uy
        ey = qz * ux - qx * uz
        ez = qx * uy - qy * ux
        out[j] = axes[i, j, 0] * ex + axes[i, j, 1] * ey + axes[i, j, 2] * ez


@njit(**_JIT)
def _last_sample_last(n_i: np.ndarray, last: int) -> np.ndarray:
    """The order (K,) that moves the leading pairs of sample ``last`` (computed first) behind the
    others: the order of ``np.nonzero``."""
    k_pairs = n_i.shape[0]
    order = np.empty(k_pairs, np.int64)
    first = 0
    while first < k_pairs and n_i[first] == last:
        first += 1
    for j in range(k_pairs - first):
        order[j] = first + j
    for j in range(first):
        order[k_pairs - first + j] = j
    return order


@njit(**_JIT, inline="always")
def _pair_needs(
    g: tuple[float, float, float],
    g2: float,
    x_clear: float,
    far: float,
    halves: float,
    v_m: float,
    inside: bool,
    end_v: np.ndarray,
    m: int,
    floor_p: float,
) -> tuple[bool, bool, bool]:
    """Whether the pair of robot capsule ``m`` and a body part needs its distance, its S_p test (no
    pair of the sample is within S_p yet: ``inside``) and its contact-speed ratio, from the bounding
    spheres: the centre offset ``g`` [m] (capsule minus part) and ``g2 = |g|^2``, the offsets at which
    the distance may be below the clearance so far (``x_clear``) and within the S_p bound (``far``)
    [m], the axes' half lengths summed (``halves``) [m], the capsule's speed bound ``v_m`` and the
    part's approach speed ``floor_p`` below which no ratio matters [m/s]."""
    fast = v_m > floor_p
    want_clear = x_clear > 0.0 and g2 <= x_clear * x_clear
    want_ratio = want_within = False
    if fast or not inside:
        if g2 < far * far:  # near enough to be within S_p
            want_within = not inside
            if fast:  # and moving toward the part fast enough to need its ratio?
                want_ratio = _approach_bound(end_v, m, g[0], g[1], g[2], g2, halves) > floor_p
    return want_clear, want_within, want_ratio


@njit(**_JIT)
def _sample_bounds(
    ra: np.ndarray,
    rb: np.ndarray,
    rr: np.ndarray,
    ha: np.ndarray,
    hb: np.ndarray,
    hr: np.ndarray,
    body_r: np.ndarray,
    nominal: np.ndarray,
    origins: np.ndarray,
    axes: np.ndarray,
    qd: np.ndarray,
    anchor: np.ndarray,
    sp_const: float,
    sp_per_speed: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the bounds of :func:`separation_summary` start from at every sample (N): each joint's body
    angular velocity and origin velocity (N, n_joints, 3) (:func:`_chain_velocities`); each robot
    capsule's end-point velocities (N, L, 2, 3) and surface speed bound and its S_p (N, 2, L)
    (:func:`_capsule_speed_bounds`) and its bounding sphere, centre and half axis length (N, L, 4) [m];
    each body part's rows of :func:`_part_spheres` (N, 7, P)."""
    n, nl = ra.shape[0], ra.shape[1]
    npart, nj = ha.shape[1], origins.shape[1]
    omega, v_o = np.empty((n, nj, 3)), np.empty((n, nj, 3))
    end_v, speed = np.empty((n, nl, 2, 3)), np.empty((n, 2, nl))
    caps, parts = np.empty((n, nl, 4)), np.empty((n, 7, npart))
    for i in range(n):
        _chain_velocities(i, origins, axes, qd, omega[i], v_o[i])
        _capsule_speed_bounds(
            i, ra, rb, rr, anchor, origins, omega[i], v_o[i], sp_const, sp_per_speed, end_v[i], speed[i, 0],
            speed[i, 1],
        )  # fmt: skip
        _part_spheres(i, ha, hb, hr, body_r, nominal, parts[i])
        for m in range(nl):
            p1x, p1y, p1z = ra[i, m, 0], ra[i, m, 1], ra[i, m, 2]
            d1x, d1y, d1z = rb[i, m, 0] - p1x, rb[i, m, 1] - p1y, rb[i, m, 2] - p1z
            caps[i, m, 0], caps[i, m, 1], caps[i, m, 2] = p1x + 0.5 * d1x, p1y + 0.5 * d1y, p1z + 0.5 * d1z
            caps[i, m, 3] = 0.5 * math.sqrt(d1x * d1x + d1y * d1y + d1z * d1z)
    return omega, v_o, end_v, speed, caps, parts


@njit(**_JIT)
def _spread(centres: np.ndarray, lo: int, hi: int, mid: int) -> float:
    """The largest distance [m] of the points ``centres[lo:hi]`` ((N, 3) rows) from ``centres[mid]``."""
    top = 0.0
    for i in range(lo, hi):
        dx = centres[i, 0] - centres[mid, 0]
        dy = centres[i, 1] - centres[mid, 1]
        dz = centres[i, 2] - centres[mid, 2]
        top = max(top, math.sqrt(dx * dx + dy * dy + dz * dz))
    return top


@njit(**_JIT)
def _block_active(
    lo: int,
    hi: int,
    caps: np.ndarray,
    rr: np.ndarray,
    speed: np.ndarray,
    parts: np.ndarray,
    floor: np.ndarray,
    best: float,
    active: np.ndarray,
) -> int:
    """The pairs that may need their distance (for the clearance, while the smallest is ``best``) or
    their contact-speed ratio at some sample of ``lo .. hi - 1``: their indices ``capsule * P +
    part``, ascending, into ``active`` (L P,); returns how many. Over the block, every sample's
    bounding sphere lies in the sphere about the middle sample's centre that holds the block's
    centres, so a pair whose spheres stay farther apart than the block's largest reaches fails the
    per-sample tests of :func:`separation_summary` at every sample of it, as does a capsule never
    faster than the part's ``floor`` for the ratio."""
    nl, npart = caps.shape[1], parts.shape[2]
    mid = (lo + hi - 1) // 2
    slack = _SLACK
    spread_p, reach_p, clear_p = np.empty(npart), np.full(npart, -np.inf), np.full(npart, -np.inf)
    count = 0
    for p in range(npart):
        spread_p[p] = _spread(parts[:, 0:3, p], lo, hi, mid)
        for i in range(lo, hi):
            reach_p[p] = max(reach_p[p], parts[i, 4, p])
            clear_p[p] = max(clear_p[p], parts[i, 6, p])
    for m in range(nl):
        spread_m = _spread(caps[:, m, 0:3], lo, hi, mid)
        big_r = v_top = sp_top = 0.0
        for i in range(lo, hi):
            big_r = max(big_r, caps[i, m, 3] + rr[m])
            v_top, sp_top = max(v_top, speed[i, 0, m]), max(sp_top, speed[i, 1, m])
        for p in range(npart):
            gx = caps[mid, m, 0] - parts[mid, 0, p]
            gy = caps[mid, m, 1] - parts[mid, 1, p]
            gz = caps[mid, m, 2] - parts[mid, 2, p]
            apart = math.sqrt(gx * gx + gy * gy + gz * gz) - spread_m - spread_p[p] - slack
            no_clear = clear_p[p] == -np.inf or apart > best + big_r + clear_p[p]
            no_ratio = v_top <= floor[p] or apart > sp_top + big_r + reach_p[p]
            if not (no_clear and no_ratio):
                active[count] = m * npart + p
                count += 1
    return count


@njit(**_JIT, inline="always")
def _pair_distance(
    i: int,
    m: int,
    p: int,
    ra: np.ndarray,
    rb: np.ndarray,
    rr: np.ndarray,
    ha: np.ndarray,
    hb: np.ndarray,
    hr: np.ndarray,
) -> tuple[float, tuple[float, float, float], tuple[float, float, float]]:
    """The distance [m] of robot capsule ``m`` and body part ``p`` at sample ``i`` (negative: they
    overlap) and the closest points of their axes [m], as :func:`capsule_distances` computes them."""
    p1x, p1y, p1z = ra[i, m, 0], ra[i, m, 1], ra[i, m, 2]
    d1x, d1y, d1z = rb[i, m, 0] - p1x, rb[i, m, 1] - p1y, rb[i, m, 2] - p1z
    p2x, p2y, p2z = ha[i, p, 0], ha[i, p, 1], ha[i, p, 2]
    d2x, d2y, d2z = hb[i, p, 0] - p2x, hb[i, p, 1] - p2y, hb[i, p, 2] - p2z
    s, t = _closest(p1x, p1y, p1z, d1x, d1y, d1z, p2x, p2y, p2z, d2x, d2y, d2z)
    x = (p1x + s * d1x, p1y + s * d1y, p1z + s * d1z)
    y = (p2x + t * d2x, p2y + t * d2y, p2z + t * d2z)
    dist = math.sqrt((x[0] - y[0]) ** 2 + (x[1] - y[1]) ** 2 + (x[2] - y[2]) ** 2) - rr[m] - hr[i, p]
    return dist, x, y


@njit(**_JIT, inline="always")
def _next_pair(
    q: int, j: int, inside: bool, active: np.ndarray, n_active: int, n_pairs: int
) -> tuple[int, int]:
    """The next pair of a sample of :func:`separation_summary` from pair ``q`` on (``capsule * P + part``)
    and the position ``j`` in the block's ``active`` pairs (its first ``n_active``): every pair until
    one is within S_p (``inside``), then only the active ones; -1 after the last."""
    if inside:
        while j < n_active and active[j] < q:
            j += 1
        return (active[j], j) if j < n_active else (-1, j)
    return (q, j) if q < n_pairs else (-1, j)


BLOCK = 8
"""Samples per block of :func:`separation_summary`'s pair bounds (:func:`_block_active`)."""


@njit(**_JIT)
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
    """What the human checks judge of the robot-body separation, without every pair's numbers
    (bounds skip the pairs that cannot matter: see the module docstring).

    Inputs as :func:`capsule_distances` and :func:`approach_speeds`, plus the body parts' radii before
    inflation ``body_r`` (P,), whether each counts toward the clearance ``nominal`` (P,) (the hand's
    do not) and the approach speed ``floor`` (P,) [m/s] below which a pair never reaches its planning
    limit. Returns per sample (N,) the smallest distance [m] to a counted part at its nominal position
    (``distance + inflation``: exact where it is the motion's smallest, at least the true value
    elsewhere, ``inf`` where no pair was computed) and whether some pair is within S_p; and the pairs
    within S_p approaching faster than their ``floor``: sample, capsule, part (K,) in the order of
    ``np.nonzero``, approach speed [m/s], S_p [m] and ``J^T u`` (K, n_joints) as :func:`pair_jtu`.

    Samples are visited in blocks of :data:`BLOCK`; once a sample has a pair within S_p (every pair
    is visited until then), only the pairs that the block's bounds do not settle are
    (:func:`_block_active`): the same pairs are computed as without the blocks.
    """
    n, nl = ra.shape[0], ra.shape[1]
    npart, nj = ha.shape[1], origins.shape[1]
    clear, within = np.full(n, np.inf), np.zeros(n, np.bool_)
    cap = 256  # rows of the pair buffers (grown when full)
    n_i, l_i, p_i = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64)
    app, sp, jtu = np.empty(cap), np.empty(cap), np.empty((cap, nj))
    k_pairs = 0
    omega, v_o, end_v, speed, caps, parts = _sample_bounds(
        ra, rb, rr, ha, hb, hr, body_r, nominal, origins, axes, qd, anchor, sp_const, sp_per_speed
    )
    active, n_active = np.empty(nl * npart, np.int64), 0
    best = np.inf  # the smallest nominal clearance computed so far (at least the motion's)
    for step in range(n):
        i = n - 1 if step == 0 else step - 1  # the last sample first: the hand-over, usually closest
        if step == 0 or i % BLOCK == 0:
            hi = n if step == 0 else min(i + BLOCK, n - 1)
            n_active = _block_active(i, hi, caps, rr, speed, parts, floor, best, active)
        inside = False
        q, j = 0, 0  # the next pair (capsule-major) and the next active one
        while True:
            q, j = _next_pair(q, j, inside, active, n_active, nl * npart)
            if q < 0:
                break
            m, p = q // npart, q % npart
            q += 1
            half_m, k, big_r = caps[i, m, 3], anchor[m], caps[i, m, 3] + rr[m]
            g = (
                caps[i, m, 0] - parts[i, 0, p],
                caps[i, m, 1] - parts[i, 1, p],
                caps[i, m, 2] - parts[i, 2, p],
            )
            g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
            x_clear, far = best + big_r + parts[i, 6, p], speed[i, 1, m] + big_r + parts[i, 4, p]
            reach = max(x_clear, far)
            if g2 > reach * reach:  # the distance >= |c_l - c_p| - R_l - R_p: most pairs
                continue
            halves, v_m = half_m + parts[i, 3, p], speed[i, 0, m]
            want_clear, want_within, want_ratio = _pair_needs(
                g, g2, x_clear, far, halves, v_m, inside, end_v[i], m, floor[p]
            )
            if not (want_ratio or want_within or want_clear):
                continue
            dist, x, y = _pair_distance(i, m, p, ra, rb, rr, ha, hb, hr)
            if nominal[p]:
                d_nom = dist + parts[i, 5, p]
                if d_nom < clear[i]:
                    clear[i] = d_nom
                if d_nom < best:
                    best = d_nom
            if not (want_ratio or want_within):
                continue
            v, ux, uy, uz, met = _surface_approach(i, k, x, y, rr[m], origins, omega[i], v_o[i])
            protective = sp_const + max(v, 0.0) * sp_per_speed
            if not dist < protective:
                continue
            inside = True
            if not v > floor[p]:
                continue
            if k_pairs == n_i.size:
                n_i, l_i, p_i, app, sp, jtu = _grow_pairs(n_i, l_i, p_i, app, sp, jtu)
            n_i[k_pairs], l_i[k_pairs], p_i[k_pairs], app[k_pairs], sp[k_pairs] = i, m, p, v, protective
            xs = (x[0] + rr[m] * ux, x[1] + rr[m] * uy, x[2] + rr[m] * uz)  # the closest surface point
            _surface_jtu(i, k, xs, ux, uy, uz, met, origins, axes, qd, jtu[k_pairs])
            k_pairs += 1
        within[i] = inside
    order = _last_sample_last(n_i[:k_pairs], n - 1)
    return clear, within, n_i[order], l_i[order], p_i[order], app[order], sp[order], jtu[order]
