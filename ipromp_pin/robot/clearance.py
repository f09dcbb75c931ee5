"""Certified self-collision clearance of a dense joint path, fast enough for every re-plan.

:func:`~ipromp_pin.robot.collision.check_self_collision` bounds the motion between two checked
samples by one reach for all collision pairs. Here every active pair ``p`` (geometries A and B) gets
its own bound: only the arm joints between A and B change their relative pose, and while the arm
moves along a straight joint-space segment from ``q`` to ``q'`` no point of the distal geometry moves,
relative to the other, by more than

    L_p(q, q') = sum_k w_pk |q'_k - q_k|

where ``w_pk`` bounds the distance from joint ``k``'s axis to any point of the distal geometry in
every configuration (the lengths of the joint offsets from joint ``k`` to the geometry's joint plus
the geometry's bounding sphere about that joint: :func:`pair_weights`). The pair's distance is
therefore Lipschitz: ``d_p(q') >= d_p(q_r) - L_p(q', q_r)``. A *ball* ``(q_r, d_p(q_r))`` certifies
every configuration with ``L_p(q, q_r) < d_p(q_r) - clearance``; ``L_p`` is convex, so a ball that
contains the joint-space box (per-joint minimum and maximum) of a stretch of path samples certifies
the piecewise-linear path through them, between the samples as well as at them (the semantics of
``check_self_collision``'s swept bound).

:class:`ClearanceCertifier` certifies a path by bisection: the whole path's box first, then halves,
quarters and so on, only for the pairs not yet certified, computing a pair's distance (Pinocchio +
coal) at the middle of a stretch that no ball covers. Balls are kept (a few per pair) and reused by
later calls, so the successive, similar paths of a closed loop need few new distance computations.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .kinematics import as_joint_path
from .model import Robot

BALLS_PER_PAIR = 8
"""Balls kept per collision pair (the oldest is replaced)."""

CHUNK = 16
"""Path segments per chunk: a ball holding a chunk's joint-space box certifies its segments at once."""

MAX_GAPS = 8
"""Runs of uncertified segments handled per pair and round (one new ball each)."""

MAX_SPLIT_DEPTH = 12
"""How many times a single path segment may be halved before the certifier gives up (1/4096)."""


def _geometry_radius(obj: pin.GeometryObject) -> float:
    """Radius in [m] of a sphere about the geometry's parent joint that contains the geometry."""
    geom = obj.geometry
    if geom.aabb_radius < 0:
        geom.computeLocalAABB()
    centre = obj.placement.act(np.asarray(geom.aabb_center, dtype=float))
    swept = geom.getSweptSphereRadius() if hasattr(geom, "getSweptSphereRadius") else 0.0
    return float(np.linalg.norm(centre) + geom.aabb_radius + max(swept, 0.0))


def pair_weights(robot: Robot) -> np.ndarray:
    """Per active collision pair, the Lipschitz weights (P, n_joints) in [m/rad] of its distance.

    ``w[p, k]`` is 0 when arm joint ``k`` does not move one geometry of pair ``p`` relative to the
    other, else an upper bound, valid in every configuration, of the distance from joint ``k``'s
    origin (on its axis) to any point of the geometry it moves.
    """
    model, (cmodel, _) = robot.model, robot.collision()
    data = model.createData()
    pin.forwardKinematics(model, data, robot.q_neutral)
    link = np.array([np.linalg.norm(data.liMi[j].translation) for j in range(model.njoints)])
    arm = [int(j) for j in robot.arm_joint_ids]
    geoms = cmodel.geometryObjects
    radius = np.array([_geometry_radius(o) for o in geoms])
    support = [set(int(s) for s in model.supports[j]) for j in range(model.njoints)]
    w = np.zeros((robot.active_pair_ids.size, len(arm)))
    for p, pid in enumerate(robot.active_pair_ids):
        cp = cmodel.collisionPairs[int(pid)]
        for g in (cp.first, cp.second):
            other = cp.second if g == cp.first else cp.first
            jg = geoms[g].parentJoint
            chain = list(model.supports[jg])  # root ... jg
            for i, k in enumerate(arm):
                if k in support[jg] and k not in support[geoms[other].parentJoint]:
                    # joint k moves geometry g relative to the other one
                    after = chain[chain.index(k) + 1 :]
                    w[p, i] = float(sum(link[j] for j in after) + radius[g])
    return w


@dataclass
class ClearanceResult:
    """Outcome of :meth:`ClearanceCertifier.certify`.

    Attributes:
        certified: Whether every pair is certified collision-free (distance above the clearance)
            along the whole piecewise-linear path.
        min_distance_m: Smallest pair distance in [m] among the computed configurations whose
            balls certify a part of the path (configurations on or near the path; 0 on failure).
        collision: Whether a computed distance was at or below the clearance.
        pair_id: The deciding collision pair (the one with ``min_distance_m``, or the failing one).
        pair: Its geometry names.
        links: Their links (parent frames).
        sample: Path sample at which the check failed (0 when certified).
        n_distances: Pair distances computed by this call.
        n_balls: Balls in the cache after the call.
        elapsed_ms: Wall time of the call in [ms].
        clearance_m: Required clearance in [m].
    """

    certified: bool
    min_distance_m: float
    collision: bool
    pair_id: int
    pair: tuple[str, str]
    links: tuple[str, str]
    sample: int
    n_distances: int
    n_balls: int
    elapsed_ms: float
    clearance_m: float


class ClearanceCertifier:
    """Certifies joint paths free of self-collision, reusing the distances it computed before.

    Not thread-safe (it uses the robot's shared work data).

    Args:
        robot: A loaded robot with its collision model.
        clearance_m: Required distance in [m] (default: the settings' ``min_clearance_m``).
        balls_per_pair: Balls kept per pair.
    """

    def __init__(self, robot: Robot, clearance_m: float | None = None, balls_per_pair: int = BALLS_PER_PAIR):
        if robot.collision_model is None:
            raise ValueError("the robot has no collision model")
        self.robot = robot
        self.clearance_m = float(robot.settings.min_clearance_m if clearance_m is None else clearance_m)
        self.weights = pair_weights(robot)  # (P, n)
        n_pairs, n = self.weights.shape
        cap = int(balls_per_pair)
        self._refs = np.zeros((n_pairs, cap, n))
        self._margin = np.full((n_pairs, cap), -np.inf)  # d - clearance; -inf: empty slot
        self._next = np.zeros(n_pairs, dtype=int)
        self._ids = robot.active_pair_ids.astype(int)
        self._pair_labels: dict[int, tuple[tuple[str, str], tuple[str, str]]] = {}
        self.n_distances_total = 0
        self._count = 0
        from . import clearance_kernels  # deferred: numba is imported (and the walk compiled) on first use

        self._kern = clearance_kernels

    @property
    def n_balls(self) -> int:
        """Balls in the cache."""
        return int(np.count_nonzero(np.isfinite(self._margin)))

    def clear(self) -> None:
        """Forget every ball."""
        self._margin[:] = -np.inf
        self._next[:] = 0

    def _segment_slack(self, p: int, a: np.ndarray, b: np.ndarray) -> float:
        """Largest ``margin - cost`` of a ball of pair ``p`` holding ``a`` and ``b`` (n,) (<= 0: none)."""
        w = self.weights[p]
        cost = np.maximum(np.abs(a - self._refs[p]) @ w, np.abs(b - self._refs[p]) @ w)
        return float(np.max(self._margin[p] - cost))

    def _distances(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Distances in [m] of ``pairs`` at arm configuration ``q`` (n,); stored as balls."""
        robot = self.robot
        model, data = robot.model, robot.data
        cmodel, cdata = robot.collision_model, robot.collision_data
        pin.forwardKinematics(model, data, robot.full_configuration(q))
        pin.updateGeometryPlacements(model, data, cmodel, cdata)
        d = np.fromiter(
            (pin.computeDistance(cmodel, cdata, int(self._ids[p])).min_distance for p in pairs),
            float,
            pairs.size,
        )
        slot = self._next[pairs]
        self._refs[pairs, slot] = q
        self._margin[pairs, slot] = d - self.clearance_m
        self._next[pairs] = (slot + 1) % self._margin.shape[1]
        self._count += pairs.size
        return d

    def _split_segment(self, p: int, a: np.ndarray, b: np.ndarray, depth: int = 0) -> float | None:
        """Certify the segment [a, b] for pair ``p`` by bisection -> its smallest slack in [m], or None
        when a distance at or below the clearance is found or the segment cannot be certified."""
        slack = self._segment_slack(p, a, b)
        if slack > 0.0:
            return slack
        if depth >= MAX_SPLIT_DEPTH:
            return None
        mid = 0.5 * (a + b)
        if self._distances(mid, np.array([p]))[0] <= self.clearance_m:
            return None
        left = self._split_segment(p, a, mid, depth + 1)
        right = None if left is None else self._split_segment(p, mid, b, depth + 1)
        return None if left is None or right is None else min(left, right)

    def closest_sample(self, q: np.ndarray, pair_id: int) -> int:
        """The sample of the path ``q`` (N, n_joints) [rad] where the balls of collision pair
        ``pair_id`` leave the least room (the smallest ``margin - L_p`` of its best ball): where its
        certified clearance is tightest."""
        p = int(np.flatnonzero(self._ids == int(pair_id))[0])
        w = self.weights[p]
        cost = np.abs(np.asarray(q, dtype=float)[:, None, :] - self._refs[p][None, :, :]) @ w  # (N, B)
        return int(np.argmin(np.max(self._margin[p][None, :] - cost, axis=1)))

    def pair_labels(self, pair_id: int) -> tuple[tuple[str, str], tuple[str, str]]:
        """The geometry and link names of collision pair ``pair_id`` (:meth:`.Robot.pair_names`,
        :meth:`.Robot.pair_links`), kept per pair: every certified path names its deciding pair."""
        labels = self._pair_labels.get(pair_id)
        if labels is None:
            labels = (self.robot.pair_names(pair_id), self.robot.pair_links(pair_id))
            self._pair_labels[pair_id] = labels
        return labels

    def certify(self, q: np.ndarray) -> ClearanceResult:
        """Certify the piecewise-linear joint path through ``q`` (N, n_joints) in [rad].

        Returns:
            The :class:`ClearanceResult` (certified; the smallest distance among the computed
            configurations whose balls certify the path; the deciding pair).
        """
        t0 = time.perf_counter()
        q = np.ascontiguousarray(as_joint_path(self.robot, q))
        if q.shape[0] == 1:
            q = np.vstack([q, q])
        self._count = 0
        n_seg = q.shape[0] - 1
        chunk = CHUNK
        n_chunks = (n_seg - 1) // chunk + 1
        # per chunk the box of its samples c * chunk .. (c + 1) * chunk (its end sample included),
        # then the whole path's
        lo = np.empty((n_chunks + 1, q.shape[1]))
        hi = np.empty_like(lo)
        starts = np.arange(n_chunks) * chunk
        np.minimum.reduceat(q, starts, axis=0, out=lo[:n_chunks])
        np.maximum.reduceat(q, starts, axis=0, out=hi[:n_chunks])
        ends = q[starts[1:]]
        np.minimum(lo[: n_chunks - 1], ends, out=lo[: n_chunks - 1])
        np.maximum(hi[: n_chunks - 1], ends, out=hi[: n_chunks - 1])
        lo[n_chunks], hi[n_chunks] = lo[:n_chunks].min(axis=0), hi[:n_chunks].max(axis=0)
        n_pairs = self.weights.shape[0]
        pairs = np.arange(n_pairs, dtype=np.int64)
        start = np.zeros(n_pairs, dtype=np.int64)
        used = np.full(n_pairs, np.inf)
        # balls placed for an uncertified segment: at its start, then at its end, then it is bisected
        tries: dict[tuple[int, int], int] = {}
        failure: tuple[bool, int, int] | None = None  # (collision, pair, sample)
        while pairs.size and failure is None:
            m = pairs.size
            gaps = np.empty((m, MAX_GAPS), dtype=np.int64)
            used_min = np.empty(m)
            self._kern.cover_walk(
                q, chunk, lo, hi, pairs, start, self._refs, self._margin, self.weights, gaps, used_min
            )
            np.minimum.at(used, pairs, used_min)
            pending = gaps[:, 0] >= 0
            pairs, gaps = pairs[pending], gaps[pending]
            start = gaps[:, 0].copy()
            todo: dict[int, list[int]] = {}  # sample -> pairs to compute there
            for i, p in enumerate(pairs.tolist()):
                for s in gaps[i][gaps[i] >= 0].tolist():
                    k = tries.get((p, s), 0)
                    if k < 2:
                        tries[(p, s)] = k + 1
                        todo.setdefault(s + k, []).append(p)
                        continue
                    bound = self._split_segment(p, q[s], q[s + 1])
                    if bound is None:
                        failure = (False, p, s)
                        break
                    used[p] = min(used[p], bound)
                    if s == start[i]:
                        start[i] = s + 1
                if failure is not None:
                    break
            for s, sel in sorted(todo.items()):
                if failure is not None:
                    break
                sel_a = np.asarray(sel, dtype=np.int64)
                d = self._distances(q[s], sel_a)
                hit = d <= self.clearance_m
                if np.any(hit):
                    failure = (True, int(sel_a[int(np.argmax(hit))]), int(s))
        self.n_distances_total += self._count
        if failure is not None:
            collision, p, sample = failure
            bound = 0.0
        else:
            collision, sample = False, 0
            p = int(np.argmin(used))
            bound = float(used[p])
        pid = int(self._ids[p])
        pair, links = self.pair_labels(pid)
        return ClearanceResult(
            certified=failure is None,
            min_distance_m=float(bound + self.clearance_m),
            collision=bool(collision),
            pair_id=pid,
            pair=pair,
            links=links,
            sample=int(sample),
            n_distances=self._count,
            n_balls=self.n_balls,
            elapsed_ms=(time.perf_counter() - t0) * 1e3,
            clearance_m=self.clearance_m,
        )
