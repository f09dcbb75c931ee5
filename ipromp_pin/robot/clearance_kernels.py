"""Compiled (numba) walk of :mod:`ipromp_pin.robot.clearance`: which path segments the cached balls
certify, per collision pair. Imported on first use (importing :mod:`ipromp_pin.robot` does not
import numba); compiled on the first call and cached on disk."""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}


@njit(**_JIT)
def _cost(q: np.ndarray, ref: np.ndarray, w: np.ndarray) -> float:
    """Weighted L1 distance ``sum_k w_k |q_k - ref_k|``."""
    s = 0.0
    for k in range(q.size):
        s += w[k] * abs(q[k] - ref[k])
    return s


@njit(**_JIT)
def _box_cost(lo: np.ndarray, hi: np.ndarray, ref: np.ndarray, w: np.ndarray) -> float:
    """Largest weighted L1 distance from ``ref`` to a point of the box [lo, hi]."""
    s = 0.0
    for k in range(lo.size):
        s += w[k] * max(abs(lo[k] - ref[k]), abs(hi[k] - ref[k]))
    return s


@njit(**_JIT)
def _best_ball(lo: np.ndarray, hi: np.ndarray, refs: np.ndarray, margin: np.ndarray, w: np.ndarray) -> int:
    """Index of the ball holding the box [lo, hi] with the largest slack (-1: none holds it)."""
    best = 0.0
    out = -1
    for b in range(margin.size):
        if margin[b] == -np.inf:
            continue
        m = margin[b] - _box_cost(lo, hi, refs[b], w)
        if m > best:
            best = m
            out = b
    return out


@njit(**_JIT)
def cover_walk(
    q: np.ndarray,
    chunk: int,
    chunk_lo: np.ndarray,
    chunk_hi: np.ndarray,
    pairs: np.ndarray,
    start: np.ndarray,
    refs: np.ndarray,
    margin: np.ndarray,
    weights: np.ndarray,
    gaps: np.ndarray,
    used_min: np.ndarray,
) -> None:
    """Find, per pair ``pairs[i]``, the path segments from sample ``start[i]`` on that no ball certifies.

    The path ``q`` (N, n) is cut into chunks of ``chunk`` segments (chunk c spans samples
    ``c * chunk`` to ``(c + 1) * chunk``, its box is ``chunk_lo[c]``, ``chunk_hi[c]`` (n,); chunk 0
    is the whole path when ``chunk_lo`` has one more row than there are chunks). A segment
    [q_s, q_s+1] is certified for pair p by a ball b (``refs[p, b]`` (n,), ``margin[p, b]`` =
    distance - clearance, -inf for an empty slot) when both end points lie strictly inside it:
    ``sum_k weights[p, k] |q_k - ref_k| < margin``; a ball holding a chunk's box certifies all its
    segments at once.

    Outputs per pair: ``gaps[i]`` the first segment of each run of uncertified segments (up to
    ``gaps.shape[1]`` runs, -1 after the last), ``used_min[i]`` the smallest margin (distance -
    clearance, in [m]) among the balls that certify a part of the path.
    """
    n_samples = q.shape[0]
    n_chunks = (n_samples - 2) // chunk + 1
    cap = refs.shape[1]
    max_gaps = gaps.shape[1]
    for i in range(pairs.size):
        p = pairs[i]
        w = weights[p]
        for g in range(max_gaps):
            gaps[i, g] = -1
        used_min[i] = np.inf
        n_gaps = 0
        if start[i] == 0:  # the whole path in one ball?
            b = _best_ball(chunk_lo[n_chunks], chunk_hi[n_chunks], refs[p], margin[p], w)
            if b >= 0:
                used_min[i] = margin[p, b]
                continue
        cur = -1
        in_gap = False
        c = start[i] // chunk
        while c < n_chunks and n_gaps < max_gaps:
            s0 = max(c * chunk, start[i])
            s1 = min((c + 1) * chunk, n_samples - 1)
            if s0 == c * chunk:
                if cur >= 0 and _box_cost(chunk_lo[c], chunk_hi[c], refs[p, cur], w) < margin[p, cur]:
                    in_gap = False
                    c += 1
                    continue
                b = _best_ball(chunk_lo[c], chunk_hi[c], refs[p], margin[p], w)
                if b >= 0:
                    cur = b
                    used_min[i] = min(used_min[i], margin[p, b])
                    in_gap = False
                    c += 1
                    continue
            for s in range(s0, s1):  # segment by segment
                if (
                    cur >= 0
                    and max(_cost(q[s], refs[p, cur], w), _cost(q[s + 1], refs[p, cur], w)) < margin[p, cur]
                ):
                    in_gap = False
                    continue
                cur = -1
                best = 0.0
                for b in range(cap):
                    if margin[p, b] == -np.inf:
                        continue
                    m = margin[p, b] - max(_cost(q[s], refs[p, b], w), _cost(q[s + 1], refs[p, b], w))
                    if m > best:
                        best = m
                        cur = b
                if cur >= 0:
                    used_min[i] = min(used_min[i], margin[p, cur])
                    in_gap = False
                elif not in_gap:
                    gaps[i, n_gaps] = s
                    n_gaps += 1
                    in_gap = True
                    if n_gaps == max_gaps:
                        break
            c += 1
