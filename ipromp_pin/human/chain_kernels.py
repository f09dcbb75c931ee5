"""Compiled (numba) loops over the arm's serial chain: its forward kinematics over many samples
(:func:`arm_frames`), its joint-space inertia (:func:`chain_mass_matrices`) and the inverse
effective masses of many pairs from it (:func:`inverse_effective_masses`). The human kernels module
(:mod:`ipromp_pin.human.separation_kernels`) exports them with the distance kernels; imported on
first use, compiled on the first call and cached on disk.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}


@njit(**_JIT)
def _axis_rotation(x: float, y: float, z: float, angle: float, out: np.ndarray) -> None:
    """The rotation (3, 3) by ``angle`` [rad] about the unit axis ``(x, y, z)`` into ``out``
    (Rodrigues' formula)."""
    c_, s_ = math.cos(angle), math.sin(angle)
    t_ = 1.0 - c_
    out[0, 0] = c_ + t_ * x * x
    out[0, 1] = t_ * x * y - s_ * z
    out[0, 2] = t_ * x * z + s_ * y
    out[1, 0] = t_ * x * y + s_ * z
    out[1, 1] = c_ + t_ * y * y
    out[1, 2] = t_ * y * z - s_ * x
    out[2, 0] = t_ * x * z - s_ * y
    out[2, 1] = t_ * y * z + s_ * x
    out[2, 2] = c_ + t_ * z * z


@njit(**_JIT)
def _rotate(rot: np.ndarray, by: np.ndarray, tmp: np.ndarray) -> None:
    """``rot <- rot @ by`` for (3, 3) matrices, through the scratch matrix ``tmp``."""
    for r in range(3):
        for c in range(3):
            tmp[r, c] = rot[r, 0] * by[0, c] + rot[r, 1] * by[1, c] + rot[r, 2] * by[2, c]
    rot[:] = tmp


@njit(**_JIT)
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
    nl = anchor.size
    origins = np.empty((n, nj, 3))
    axes = np.empty((n, nj, 3))
    ca = np.empty((n, nl, 3))
    cb = np.empty((n, nl, 3))
    rots = np.empty((nj, 3, 3))
    rot = np.empty((3, 3))
    tmp = np.empty((3, 3))
    kx = np.empty((3, 3))
    for i in range(n):
        pos = np.zeros(3)
        rot[:] = 0.0
        rot[0, 0] = rot[1, 1] = rot[2, 2] = 1.0
        for k in range(nj):
            for r in range(3):
                pos[r] += rot[r, 0] * x0[k, 0, 3] + rot[r, 1] * x0[k, 1, 3] + rot[r, 2] * x0[k, 2, 3]
            for r in range(3):
                for c in range(3):
                    tmp[r, c] = rot[r, 0] * x0[k, 0, c] + rot[r, 1] * x0[k, 1, c] + rot[r, 2] * x0[k, 2, c]
            rot[:] = tmp
            origins[i, k] = pos
            for r in range(3):
                axes[i, k, r] = rot[r, 0] * axis[k, 0] + rot[r, 1] * axis[k, 1] + rot[r, 2] * axis[k, 2]
            # Rodrigues rotation about the local axis by q[i, k]
            _axis_rotation(axis[k, 0], axis[k, 1], axis[k, 2], q[i, k], kx)
            _rotate(rot, kx, tmp)
            rots[k] = rot
        for m in range(nl):
            k = anchor[m]
            for r in range(3):
                ca[i, m, r] = origins[i, k, r] + (
                    rots[k, r, 0] * a_local[m, 0]
                    + rots[k, r, 1] * a_local[m, 1]
                    + rots[k, r, 2] * a_local[m, 2]
                )
                cb[i, m, r] = origins[i, k, r] + (
                    rots[k, r, 0] * b_local[m, 0]
                    + rots[k, r, 1] * b_local[m, 1]
                    + rots[k, r, 2] * b_local[m, 2]
                )
    return origins, axes, ca, cb


@njit(**_JIT)
def inverse_effective_masses(mass: np.ndarray, sample: np.ndarray, jtu: np.ndarray) -> np.ndarray:
    """``u^T J M^-1 J^T u`` [1/kg] per pair: ``mass`` (S, n, n) the arm's inertia at S samples,
    ``sample`` (K,) which one each pair uses, ``jtu`` (K, n) its ``J^T u``; one Cholesky
    factorisation per sample and a forward substitution per pair (``|L^-1 J^T u|^2``)."""
    k_pairs, nj = jtu.shape
    out = np.empty(k_pairs)
    lowers = np.empty_like(mass)
    for s in range(mass.shape[0]):
        lowers[s] = np.linalg.cholesky(mass[s])
    y = np.empty(nj)
    for k in range(k_pairs):
        low = lowers[sample[k]]
        acc = 0.0
        for i in range(nj):
            v = jtu[k, i]
            for j in range(i):
                v -= low[i, j] * y[j]
            y[i] = v / low[i, i]
            acc += y[i] * y[i]
        out[k] = acc
    return out


@njit(**_JIT)
def chain_mass_matrices(
    q: np.ndarray,
    placement: np.ndarray,
    axis: np.ndarray,
    mass: np.ndarray,
    com: np.ndarray,
    inertia: np.ndarray,
) -> np.ndarray:
    """Joint-space inertia matrices (S, n, n) [kg m^2] of a serial chain of n revolute joints at
    angles ``q`` (S, n) [rad]: ``placement`` (n, 4, 4) each joint's frame in its parent's at zero
    angle, ``axis`` (n, 3) its unit axis in its own frame, and each body's ``mass`` (n,) [kg],
    centre of mass ``com`` (n, 3) [m] and rotational inertia about it ``inertia`` (n, 3, 3)
    [kg m^2], in its joint's frame (what CRBA computes, as
    ``M_ij = sum_{b >= max(i, j)} m_b (z_i x (c_b - o_i)) . (z_j x (c_b - o_j)) + z_i . I_b z_j``)."""
    s_n, n = q.shape
    out = np.empty((s_n, n, n))
    rot = np.empty((3, 3))
    tmp = np.empty((3, 3))
    kx = np.empty((3, 3))
    o = np.empty((n, 3))
    z = np.empty((n, 3))
    c = np.empty((n, 3))
    ib = np.empty((n, 3, 3))
    for si in range(s_n):
        pos = np.zeros(3)
        rot[:] = 0.0
        rot[0, 0] = rot[1, 1] = rot[2, 2] = 1.0
        for k in range(n):
            for r in range(3):
                pos[r] += (
                    rot[r, 0] * placement[k, 0, 3]
                    + rot[r, 1] * placement[k, 1, 3]
                    + rot[r, 2] * placement[k, 2, 3]
                )
            for r in range(3):
                for cc in range(3):
                    tmp[r, cc] = (
                        rot[r, 0] * placement[k, 0, cc]
                        + rot[r, 1] * placement[k, 1, cc]
                        + rot[r, 2] * placement[k, 2, cc]
                    )
            rot[:] = tmp
            _axis_rotation(axis[k, 0], axis[k, 1], axis[k, 2], q[si, k], kx)
            _rotate(rot, kx, tmp)
            for r in range(3):
                o[k, r] = pos[r]
                z[k, r] = rot[r, 0] * axis[k, 0] + rot[r, 1] * axis[k, 1] + rot[r, 2] * axis[k, 2]
                c[k, r] = pos[r] + rot[r, 0] * com[k, 0] + rot[r, 1] * com[k, 1] + rot[r, 2] * com[k, 2]
            for r in range(3):  # R I R^T
                for cc in range(3):
                    tmp[r, cc] = (
                        rot[r, 0] * inertia[k, 0, cc]
                        + rot[r, 1] * inertia[k, 1, cc]
                        + rot[r, 2] * inertia[k, 2, cc]
                    )
            for r in range(3):
                for cc in range(3):
                    ib[k, r, cc] = tmp[r, 0] * rot[cc, 0] + tmp[r, 1] * rot[cc, 1] + tmp[r, 2] * rot[cc, 2]
        for i in range(n):
            for j in range(i, n):
                acc = 0.0
                for b in range(j, n):
                    lix, liy, liz = c[b, 0] - o[i, 0], c[b, 1] - o[i, 1], c[b, 2] - o[i, 2]
                    ljx, ljy, ljz = c[b, 0] - o[j, 0], c[b, 1] - o[j, 1], c[b, 2] - o[j, 2]
                    aix = z[i, 1] * liz - z[i, 2] * liy
                    aiy = z[i, 2] * lix - z[i, 0] * liz
                    aiz = z[i, 0] * liy - z[i, 1] * lix
                    ajx = z[j, 1] * ljz - z[j, 2] * ljy
                    ajy = z[j, 2] * ljx - z[j, 0] * ljz
                    ajz = z[j, 0] * ljy - z[j, 1] * ljx
                    rot_term = 0.0
                    for r in range(3):
                        rot_term += z[i, r] * (
                            ib[b, r, 0] * z[j, 0] + ib[b, r, 1] * z[j, 1] + ib[b, r, 2] * z[j, 2]
                        )
                    acc += mass[b] * (aix * ajx + aiy * ajy + aiz * ajz) + rot_term
                out[si, i, j] = acc
                out[si, j, i] = acc
    return out
