"""Retargeting through the gripper: a joint path of one arm (the source, e.g. Baxter's left arm, whose
recordings trained the model) becomes the joint path of another arm placed in the same scene.

The source's forward kinematics give the gripper's pose path (its ``ee`` frame, in the source's base
frame: the scene frame); the target arm, built at its ``[placement]`` in that frame
(:class:`~ipromp_pin.robot.settings.Placement`), follows the same poses of its own ``ee`` frame by
inverse kinematics along the path. Each sample starts from the previous solution and takes damped
least-squares steps on the full pose error (``log6`` of the remaining transform, in the end-effector
frame); a redundant arm (7 joints for a 6-D pose) spends its spare freedom in the Jacobian's null
space pulling every joint toward the middle of its range (weighted by the inverse squared range), which
keeps it away from its limits. The hand-over pose (the path's last) is solved first, from a few
deterministic seeds, and the path is followed back from it. Sampled paths of the prediction are transferred by
one linearised step around the mean's solution (their hand-over configurations exactly).

The pose path may also come straight from a model whose robot side is a gripper pose path (no
source joints): :func:`follow_pose_path` and :func:`follow_pose_samples` take the poses.

:class:`PoseSolver` solves whole paths in one call of the compiled kernels
(:mod:`ipromp_pin.robot.ik_kernels`, the chain read by :mod:`ipromp_pin.robot.arm_chain`) when the
kernel switch's set ``"ik"`` is compiled; its Pinocchio iterations (:meth:`PoseSolver.solve`,
:meth:`PoseSolver.first`) are the reference, and what runs otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from ..exceptions import InfeasibleError
from .arm_chain import arm_chain, chain_placements, ik_kernels, run_compiled
from .kinematics import as_joint_path, frame_placements
from .model import Robot

TOL_M = 1e-3
"""Largest gripper position residual [m] at which a pose counts as reached (1 mm)."""

TOL_RAD = float(np.radians(0.5))
"""Largest gripper orientation residual [rad] at which a pose counts as reached (0.5 deg)."""

NULL_SPACE_GAIN = 0.1
"""Fraction of the way toward the middle of the limits (weighted by the inverse squared range, the
narrowest joint at full weight) each sample's first step takes in the pose task's null space."""

TRACK_ITERATIONS = 10
"""Iterations per path sample, each started from the previous sample's solution (one or two suffice
on a smooth path)."""

MAX_STEP_RAD = 0.3
"""Largest joint step of one iteration [rad]: far from the pose, a full Gauss-Newton step overshoots
(without it the UR5 reached a synthetic hand-over pose from none of 10 random seeds, with it it
reaches all 60 synthetic hand-over poses; ``benchmarks/placement.py``)."""

GOOD_MARGIN = 0.05
"""A first solution this far from every limit (as a fraction of the joint's range) is kept without
trying the other seeds."""

N_SEEDS = 8
"""Start configurations tried for the first pose (the middle of the limits, then fixed random ones)."""

SAME_SOLUTION_RAD = 0.05
"""Two solutions of one pose closer than this in every joint [rad] are the same candidate."""

Preference = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""Scores candidate joint paths of one pose path, given at some of its samples (S, K, n_joints)
[rad] with those samples' indices (K,): (S,), higher preferred (e.g.
:func:`ipromp_pin.planning.transfer.kindest_to_human`)."""

SCORED_SAMPLES = 21
"""Samples of a candidate path (evenly spaced, both ends included) that :func:`follow_pose_path`
follows to score it: the chosen candidate is then followed at every sample."""


@dataclass(frozen=True)
class TransferredPath:
    """A joint path of the target arm that follows the source's gripper poses.

    Attributes:
        q: (M, n_target_joints) joint angles of the target arm in [rad].
        position_error_m: (M,) remaining gripper position error per sample in [m].
        rotation_error_rad: (M,) remaining gripper orientation error per sample in [rad].
        jacobians: (M, 6, n_target_joints) the ee frame's Jacobians (local frame) at ``q``.
    """

    q: np.ndarray
    position_error_m: np.ndarray
    rotation_error_rad: np.ndarray
    jacobians: np.ndarray

    @property
    def reached(self) -> bool:
        """Whether the last pose (the hand-over) is reached within :data:`TOL_M` and :data:`TOL_RAD`."""
        return bool(self.position_error_m[-1] <= TOL_M and self.rotation_error_rad[-1] <= TOL_RAD)

    @property
    def handover_residual_mm(self) -> float:
        """Gripper position residual at the hand-over in [mm]."""
        return float(self.position_error_m[-1] * 1e3)

    @property
    def handover_residual_deg(self) -> float:
        """Gripper orientation residual at the hand-over in [deg]."""
        return float(np.degrees(self.rotation_error_rad[-1]))

    @property
    def max_path_residual_mm(self) -> float:
        """Largest gripper position residual along the path in [mm]."""
        return float(np.max(self.position_error_m) * 1e3)

    def why_not_reached(self, target: Robot) -> str:
        """One clause: how far the target arm stays from the hand-over pose."""
        return (
            f"robot '{target.settings.name}' cannot reach the hand-over pose at its placement: inverse "
            f"kinematics stops {self.handover_residual_mm:.1f} mm and {self.handover_residual_deg:.2f} deg "
            f"away (at most {TOL_M * 1e3:g} mm and {np.degrees(TOL_RAD):g} deg)"
        )


@dataclass(frozen=True)
class SolveSteps:
    """Poses to solve in turn (:meth:`PoseSolver.follow`): step ``t`` solves pose ``order[t]`` from
    the solution of pose ``seed_from[t]`` (solved earlier) or, where that is negative, from
    ``seeds[t]``, with at most ``max_iters[t]`` iterations.

    Attributes:
        order: (T,) pose indices.
        seed_from: (T,) pose whose solution seeds the step (-1: ``seeds[t]``).
        seeds: (T, n) start configurations [rad] (read where ``seed_from`` is negative).
        max_iters: (T,) iteration limits.
    """

    order: np.ndarray
    seed_from: np.ndarray
    seeds: np.ndarray
    max_iters: np.ndarray

    @classmethod
    def chained(cls, order: list[int] | np.ndarray, seed_from: list[int] | np.ndarray, n: int) -> SolveSteps:
        """Each pose of ``order`` from the solution of ``seed_from`` (:data:`TRACK_ITERATIONS`)."""
        order = np.asarray(order, dtype=np.int64)
        return cls(
            order,
            np.asarray(seed_from, dtype=np.int64),
            np.zeros((order.size, n)),
            np.full(order.size, TRACK_ITERATIONS, dtype=np.int64),
        )

    @classmethod
    def seeded(cls, seeds: np.ndarray, max_iter: int) -> SolveSteps:
        """Pose ``i`` from ``seeds[i]`` (M, n) [rad] for every ``i``, at most ``max_iter`` iterations."""
        m = seeds.shape[0]
        return cls(
            np.arange(m, dtype=np.int64),
            np.full(m, -1, dtype=np.int64),
            np.ascontiguousarray(seeds, dtype=float),
            np.full(m, max_iter, dtype=np.int64),
        )

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The four arrays as the compiled kernel takes them (int64, float64, C order)."""
        return (
            np.ascontiguousarray(self.order, dtype=np.int64),
            np.ascontiguousarray(self.seed_from, dtype=np.int64),
            np.ascontiguousarray(self.seeds, dtype=float),
            np.ascontiguousarray(self.max_iters, dtype=np.int64),
        )


@dataclass(frozen=True)
class PathSolution:
    """Work arrays of :meth:`PoseSolver.follow`: joint angles ``q`` (M, n) [rad], errors ``err``
    (M, 2) (position [m], orientation [rad]) and Jacobians ``jacs`` (M, 6, n)."""

    q: np.ndarray
    err: np.ndarray
    jacs: np.ndarray

    @classmethod
    def empty(cls, m: int, n: int) -> PathSolution:
        """Arrays for ``m`` poses of an arm of ``n`` joints."""
        return cls(np.empty((m, n)), np.empty((m, 2)), np.empty((m, 6, n)))

    def set(self, i: int, solution: tuple[np.ndarray, float, float, np.ndarray]) -> None:
        """Store ``(q, err_p, err_r, jac)`` as pose ``i``'s solution."""
        self.q[i], self.err[i, 0], self.err[i, 1], self.jacs[i] = solution

    def reached(self, i: int) -> bool:
        """Whether pose ``i`` is reached within :data:`TOL_M` and :data:`TOL_RAD`."""
        return bool(self.err[i, 0] <= TOL_M and self.err[i, 1] <= TOL_RAD)

    def path(self) -> TransferredPath:
        """The solution as a :class:`TransferredPath`."""
        return TransferredPath(self.q, self.err[:, 0].copy(), self.err[:, 1].copy(), self.jacs)


def gripper_poses(robot: Robot, q: np.ndarray) -> list[pin.SE3]:
    """The ``ee`` frame's poses (M,) in the scene frame along a joint path (M, n_joints) [rad]."""
    pos, rot = frame_placements(robot, q)
    return [pin.SE3(r, p) for p, r in zip(pos, rot, strict=True)]


class PoseSolver:
    """Damped least-squares IK of one target arm's ``ee`` frame (work buffers of the robot)."""

    def __init__(self, robot: Robot, damping: float = 1e-6, max_iter: int = 60) -> None:
        self.robot = robot
        self.lo = robot.lower_rad + robot.settings.position_margin_rad
        self.hi = robot.upper_rad - robot.settings.position_margin_rad
        self.mid = 0.5 * (self.lo + self.hi)
        weight = 1.0 / np.maximum(self.hi - self.lo, 1e-6) ** 2
        self.pull = weight / weight.max()
        self.damping = damping
        self.max_iter = max_iter
        self.eye_n = np.eye(robot.n_joints)
        self.eye_6 = np.eye(6)
        self._full = robot.full_configuration(self.mid)  # the full configuration, arm joints set per call
        self._q_index = robot.arm_q_index
        self._v_index = robot.arm_v_index
        self.chain = arm_chain(robot)  # None: not a serial revolute chain, Pinocchio's iterations only
        self._limits = np.ascontiguousarray(np.vstack([self.lo, self.hi, self.mid, self.pull]))
        self._params = np.array([damping, TOL_M * 0.1, TOL_RAD * 0.1, NULL_SPACE_GAIN, MAX_STEP_RAD])
        self._reach = np.array([TOL_M, TOL_RAD, GOOD_MARGIN])

    def error(self, q: np.ndarray, target: pin.SE3) -> tuple[np.ndarray, np.ndarray, pin.SE3]:
        """The pose error (6,) in the ee frame, its Jacobian (6, n) and the remaining transform."""
        r = self.robot
        full = self._full
        full[self._q_index] = q
        pin.forwardKinematics(r.model, r.data, full)
        current = pin.updateFramePlacement(r.model, r.data, r.ee_frame_id)
        rest = current.actInv(target)
        jac_local = pin.computeFrameJacobian(r.model, r.data, full, r.ee_frame_id, pin.LOCAL)[
            :, self._v_index
        ]
        return pin.log6(rest).vector, pin.Jlog6(rest.inverse()) @ jac_local, rest

    def solve(
        self, target: pin.SE3, seed: np.ndarray, max_iter: int | None = None
    ) -> tuple[np.ndarray, float, float, np.ndarray]:
        """Joint angles (n,), position and orientation errors [m], [rad] and the Jacobian (6, n),
        from ``seed``: the first step also moves toward the middle of the limits in the pose task's
        null space, the next ones only reduce the pose error (to a tenth of the tolerances)."""
        q = np.clip(seed, self.lo, self.hi)
        tol_m, tol_r = TOL_M * 0.1, TOL_RAD * 0.1
        jac = np.zeros((6, self.robot.n_joints))
        err_p = err_r = np.inf
        for k in range(self.max_iter if max_iter is None else max_iter):
            e, jac, rest = self.error(q, target)
            err_p = float(np.linalg.norm(rest.translation))
            err_r = float(np.linalg.norm(e[3:]))
            if err_p <= tol_m and err_r <= tol_r:
                break
            pinv = jac.T @ np.linalg.solve(jac @ jac.T + self.damping * self.eye_6, self.eye_6)
            step = pinv @ e
            if k == 0:  # spare freedom: toward the middle of the limits
                step += (self.eye_n - pinv @ jac) @ (NULL_SPACE_GAIN * self.pull * (self.mid - q))
            largest = float(np.max(np.abs(step)))
            if largest > MAX_STEP_RAD:  # far from the pose the linearisation does not hold
                step *= MAX_STEP_RAD / largest
            q = np.clip(q + step, self.lo, self.hi)
        return q, err_p, err_r, jac

    def margin(self, q: np.ndarray) -> float:
        """Smallest distance to a limit as a fraction of the joint's range."""
        return float(np.min(np.minimum(q - self.lo, self.hi - q) / (self.hi - self.lo)))

    def first(self, target: pin.SE3, seed: np.ndarray | None) -> tuple[np.ndarray, float, float, np.ndarray]:
        """A pose from no previous solution: from ``seed`` (if given), the middle of the limits, then
        fixed random seeds (up to :data:`N_SEEDS`), the first converged solution at least
        :data:`GOOD_MARGIN` from every limit, else the converged one with the largest margin, else
        the one closest to the pose."""
        best, best_key = None, None
        for s in self.seeds(seed):
            out = self.solve(target, s)
            ok = out[1] <= TOL_M and out[2] <= TOL_RAD
            key = (ok, self.margin(out[0]) if ok else -(out[1] + 0.1 * out[2]))
            if best_key is None or key > best_key:
                best, best_key = out, key
            if ok and key[1] >= GOOD_MARGIN:
                break
        assert best is not None
        return best

    def seeds(self, seed: np.ndarray | None) -> np.ndarray:
        """The start configurations (S, n) [rad] of :meth:`first`: ``seed`` (if given), the middle of
        the limits, then fixed random ones."""
        drawn = np.random.default_rng(0).uniform(self.lo, self.hi, size=(N_SEEDS - 1, self.robot.n_joints))
        first = [self.mid] if seed is None else [np.asarray(seed, dtype=float).reshape(-1), self.mid]
        return np.ascontiguousarray(np.vstack(first + [drawn]))

    def first_pose(
        self, rot: np.ndarray, pos: np.ndarray, seed: np.ndarray | None
    ) -> tuple[np.ndarray, float, float, np.ndarray]:
        """:meth:`first` for the pose ``rot`` (3, 3), ``pos`` (3,) [m], in one compiled call when the
        kernels are in use."""
        if self.chain is not None:
            q, jac = np.empty(self.robot.n_joints), np.empty((6, self.robot.n_joints))
            c = self.chain
            args = (self._limits, self._params, self._reach, c.x0, c.axis, c.ee, q, jac)
            rot_, pos_ = np.ascontiguousarray(rot, dtype=float), np.ascontiguousarray(pos, dtype=float)
            out = run_compiled("solve_first", rot_, pos_, self.seeds(seed), self.max_iter, *args)
            if out is not None:
                err_p, err_r = out
                return q, float(err_p), float(err_r), jac
        return self.first(pin.SE3(rot, pos), seed)

    def good_poses(
        self, rot: np.ndarray, pos: np.ndarray, seed: np.ndarray | None = None
    ) -> list[tuple[np.ndarray, float, float, np.ndarray]]:
        """The distinct solutions (q, position and orientation errors, Jacobian) of the pose ``rot``
        (3, 3), ``pos`` (3,) [m] that the seeds of :meth:`seeds` reach at least :data:`GOOD_MARGIN`
        from every limit, in seed order (two within :data:`SAME_SOLUTION_RAD` count once)."""
        seeds = self.seeds(seed)
        s = seeds.shape[0]
        out = PathSolution.empty(s, self.robot.n_joints)
        rots = np.ascontiguousarray(np.broadcast_to(rot, (s, 3, 3)), dtype=float)
        poss = np.ascontiguousarray(np.broadcast_to(pos, (s, 3)), dtype=float)
        self.follow(rots, poss, SolveSteps.seeded(seeds, self.max_iter), out)
        kept: list[int] = []
        for i in range(s):
            if not out.reached(i) or self.margin(out.q[i]) < GOOD_MARGIN:
                continue
            if all(np.max(np.abs(out.q[i] - out.q[k])) > SAME_SOLUTION_RAD for k in kept):
                kept.append(i)
        return [(out.q[i], float(out.err[i, 0]), float(out.err[i, 1]), out.jacs[i]) for i in kept]

    def prime(self) -> None:
        """Load (or compile) the compiled kernels now, so that no later call pays for it: the pose at
        the middle of the limits, solved from there (nothing when Pinocchio's iterations run)."""
        if self.chain is None or ik_kernels() is None:
            return
        pos, rot = chain_placements(self.robot, self.mid[None])
        self.first_pose(rot[0], pos[0], self.mid)
        self.follow(
            rot, pos, SolveSteps.seeded(self.mid[None], 1), PathSolution.empty(1, self.robot.n_joints)
        )

    def follow(self, rot: np.ndarray, pos: np.ndarray, steps: SolveSteps, out: PathSolution) -> None:
        """Solve the poses ``rot`` (M, 3, 3), ``pos`` (M, 3) [m] in the order of ``steps`` into
        ``out``, in one compiled call when the kernels are in use, else by :meth:`solve`."""
        if self.chain is not None:
            c = self.chain
            done = run_compiled(
                "solve_sequence",
                np.ascontiguousarray(rot, dtype=float),
                np.ascontiguousarray(pos, dtype=float),
                *steps.arrays(),
                self._limits,
                self._params,
                c.x0,
                c.axis,
                c.ee,
                out.q,
                out.err,
                out.jacs,
            )
            if done is not None:
                return
        for t, i in enumerate(steps.order):
            start = out.q[steps.seed_from[t]] if steps.seed_from[t] >= 0 else steps.seeds[t]
            out.set(int(i), self.solve(pin.SE3(rot[i], pos[i]), start, int(steps.max_iters[t])))


def transfer_path(
    source: Robot,
    target: Robot,
    q_source: np.ndarray,
    q_seed: np.ndarray | None = None,
    prefer: Preference | None = None,
) -> TransferredPath:
    """The target arm's joint path whose gripper follows the source arm's gripper along ``q_source``.

    Args:
        source: The robot of the joint path (its base frame is the scene frame).
        target: The arm that executes it, built at its ``[placement]`` in the source's base frame.
        q_source: (M, n_source_joints) source joint path in [rad].
        q_seed: (n_target_joints,) start configuration for the first pose (default: fixed seeds).
        prefer: Chooses among the paths to the hand-over configurations the seeds reach
            (:func:`follow_pose_path`).

    Raises:
        InfeasibleError: the target is not placed in the source's scene.

    The source's forward kinematics give the pose path that :func:`follow_pose_path` follows.
    """
    check_pair(source, target)
    q_source = as_joint_path(source, q_source, "source joint path")
    pos, rot = chain_placements(source, q_source)
    return follow_pose_path(target, pos, rot, q_seed, prefer)


def follow_pose_path(
    target: Robot,
    positions: np.ndarray,
    rotations: np.ndarray,
    q_seed: np.ndarray | None = None,
    prefer: Preference | None = None,
) -> TransferredPath:
    """The target arm's joint path whose ``ee`` frame follows a gripper pose path in the scene frame
    (the target's model frame: its placement applied).

    Args:
        target: The executing arm.
        positions: (M, 3) gripper positions in [m].
        rotations: (M, 3, 3) gripper rotation matrices.
        q_seed: (n_target_joints,) start configuration for the first pose (default: fixed seeds).
        prefer: Chooses among the paths back from the hand-over configurations the seeds reach
            (:meth:`PoseSolver.good_poses`; None: the first one far enough from the limits).

    The hand-over pose (the last) is solved first, then the path is followed back from it to the
    start, each sample from the next one's solution. When the target cannot reach the hand-over, every
    sample holds that best attempt and :attr:`TransferredPath.reached` is False (the caller refuses
    the plan).
    """
    pos = np.ascontiguousarray(positions, dtype=float)
    rot = np.ascontiguousarray(rotations, dtype=float)
    solver = PoseSolver(target)
    m, n = pos.shape[0], target.n_joints
    back = np.arange(m - 2, -1, -1)  # back from the hand-over: the path leads to that solution
    ends = [] if prefer is None else solver.good_poses(rot[-1], pos[-1], q_seed)
    if prefer is not None and len(ends) > 1:  # several ways to meet the hand-over: the best-scored
        scores, followed = _scored(solver, rot, pos, ends, prefer)
        # a path the arm can follow to its start beats one it cannot, whatever the preference
        ends = [ends[max(range(len(ends)), key=lambda i: (bool(followed[i]), float(scores[i])))]]
    out = PathSolution.empty(m, n)
    out.set(m - 1, ends[0] if ends else solver.first_pose(rot[-1], pos[-1], q_seed))
    if not out.reached(m - 1):  # out of reach: refused, the path is not followed
        out.q[:], out.err[:], out.jacs[:] = out.q[-1], out.err[-1], out.jacs[-1]
        return out.path()
    solver.follow(rot, pos, SolveSteps.chained(back, back + 1, n), out)
    return out.path()


def kindest_start(
    solver: PoseSolver,
    rot: np.ndarray,
    pos: np.ndarray,
    motions: Sequence[tuple[np.ndarray, np.ndarray, Preference]],
) -> np.ndarray | None:
    """The configuration (n,) [rad] in which the arm best starts from the pose ``rot`` (3, 3), ``pos``
    (3,) [m] the ``motions`` it may be asked to make from there, each a pose path (positions (M, 3)
    [m], rotations (M, 3, 3); its first pose is taken to be the start) with the preference scoring
    the arm's paths along it: of the distinct configurations the seeds reach
    (:meth:`PoseSolver.good_poses`), the one from which the arm follows the most motions to their
    end, then scores above -inf in the most, then has the largest sum of finite scores. None when the
    seeds reach one configuration at most (nothing to choose)."""
    ends = solver.good_poses(rot, pos)
    if len(ends) < 2:
        return None
    keys = np.zeros((len(ends), 3))
    for m_pos, m_rot, prefer in motions:
        m = m_pos.shape[0]
        # forward from the start: the same following as back from a hand-over, on the reversed path
        r = np.ascontiguousarray(np.concatenate([rot[None], m_rot[1:]])[::-1])
        p = np.ascontiguousarray(np.concatenate([pos[None], m_pos[1:]])[::-1])

        def forward(
            paths: np.ndarray, samples: np.ndarray, prefer: Preference = prefer, m: int = m
        ) -> np.ndarray:
            return prefer(paths[:, ::-1], (m - 1 - samples)[::-1])

        scores, followed = _scored(solver, r, p, ends, forward)
        finite = np.isfinite(scores)
        keys += np.stack([followed, finite, np.where(finite, scores, 0.0)], axis=1)
    best = max(range(len(ends)), key=lambda i: tuple(keys[i]))
    return np.array(ends[best][0], dtype=float)


def _scored(
    solver: PoseSolver,
    rot: np.ndarray,
    pos: np.ndarray,
    ends: list[tuple[np.ndarray, float, float, np.ndarray]],
    prefer: Preference,
) -> tuple[np.ndarray, np.ndarray]:
    """``prefer``'s scores (S,) of the paths back from the hand-over solutions ``ends`` along the
    poses ``rot`` (M, 3, 3), ``pos`` (M, 3) [m], each followed at :data:`SCORED_SAMPLES` samples, and
    whether each reaches every one of those poses (S,) (within :data:`TOL_M` and :data:`TOL_RAD`:
    from some solutions the arm runs into its limits on the way back)."""
    m, n = pos.shape[0], solver.robot.n_joints
    samples = np.unique(np.linspace(0, m - 1, min(SCORED_SAMPLES, m)).round().astype(np.int64))
    k = samples.size
    r, p = np.ascontiguousarray(rot[samples]), np.ascontiguousarray(pos[samples])
    back = np.arange(k - 2, -1, -1)
    paths = np.empty((len(ends), k, n))
    followed = np.empty(len(ends), dtype=bool)
    for i, end in enumerate(ends):
        out = PathSolution.empty(k, n)
        out.set(k - 1, end)
        solver.follow(r, p, SolveSteps.chained(back, back + 1, n), out)
        paths[i] = out.q
        followed[i] = all(out.reached(j) for j in range(k))
    return np.asarray(prefer(paths, samples), dtype=float), followed


def transfer_samples(
    source: Robot,
    target: Robot,
    q_source_samples: np.ndarray,
    mean: TransferredPath,
    q_source_mean: np.ndarray,
) -> np.ndarray:
    """Sampled source joint paths (n, M, n_source) [rad] as target joint paths (n, M, n_target) [rad]:
    one linearised step around ``mean`` (the transferred mean path, same M) per sample and time, then
    exact inverse kinematics for each sample's last configuration (the hand-over, which the uncertainty
    check uses)."""
    solver = PoseSolver(target)
    chain = arm_chain(source)
    moved = None
    if chain is not None:
        moved = run_compiled(
            "linearised_samples",
            np.ascontiguousarray(q_source_samples, dtype=float),
            chain.x0,
            chain.axis,
            chain.ee,
            *chain_placements(source, q_source_mean),
            np.ascontiguousarray(mean.jacobians),
            np.ascontiguousarray(mean.q),
            float(solver.damping),
        )
    out, end_pos, end_rot = (
        moved
        if moved is not None
        else linearised_samples(source, q_source_samples, mean, q_source_mean, solver.damping)
    )
    return exact_handovers(solver, out, end_pos, end_rot)


def linearised_samples(
    source: Robot,
    q_source_samples: np.ndarray,
    mean: TransferredPath,
    q_source_mean: np.ndarray,
    damping: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference of the compiled ``linearised_samples``: sampled source paths (n, M, n_source)
    [rad] moved by one damped least-squares step around ``mean`` (n, M, n_target) [rad], and the
    samples' last gripper poses (n, 3) [m], (n, 3, 3)."""
    n_s, m, _ = q_source_samples.shape
    pm, rm = frame_placements(source, q_source_mean)  # (M, 3), (M, 3, 3)
    ps, rs = frame_placements(source, q_source_samples.reshape(n_s * m, -1))
    ps, rs = ps.reshape(n_s, m, 3), rs.reshape(n_s, m, 3, 3)
    return pose_step(ps, rs, pm, rm, mean, damping), ps[:, -1], rs[:, -1]


def pose_step(
    ps: np.ndarray, rs: np.ndarray, pm: np.ndarray, rm: np.ndarray, mean: TransferredPath, damping: float
) -> np.ndarray:
    """Sampled gripper poses (positions (n, M, 3) [m], rotations (n, M, 3, 3)) as one damped
    least-squares step (n, M, n_target) [rad] around ``mean``, the joint path followed for the
    poses ``pm`` (M, 3), ``rm`` (M, 3, 3)."""
    n_s = ps.shape[0]
    # the sample's pose in the mean's gripper frame, to first order: translation and rotation vector
    dp = np.einsum("mji,smj->smi", rm, ps - pm)
    rel = np.einsum("mji,smjk->smik", rm, rs)
    dr = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(n_s, -1, 3)
    jac = mean.jacobians  # (M, 6, n)
    jjt = np.einsum("mij,mkj->mik", jac, jac) + damping * np.eye(6)
    step = np.linalg.solve(jjt[None], np.concatenate([dp, dr], axis=2)[..., None])[..., 0]  # (n_s, M, 6)
    return mean.q[None] + np.einsum("mji,smj->smi", jac, step)


def follow_pose_samples(
    target: Robot,
    positions: np.ndarray,
    rotations: np.ndarray,
    mean: TransferredPath,
    mean_positions: np.ndarray,
    mean_rotations: np.ndarray,
) -> np.ndarray:
    """Sampled gripper pose paths (positions (n, M, 3) [m], rotations (n, M, 3, 3)) as target joint
    paths (n, M, n_target) [rad]: one linearised step around ``mean`` (the followed mean path, of the
    poses ``mean_positions`` (M, 3), ``mean_rotations`` (M, 3, 3)) per sample and time
    (:func:`pose_step`), then exact inverse kinematics for each sample's last configuration (the
    hand-over, which the uncertainty check uses)."""
    ps = np.asarray(positions, dtype=float)
    rs = np.asarray(rotations, dtype=float)
    solver = PoseSolver(target)
    out = pose_step(ps, rs, mean_positions, mean_rotations, mean, float(solver.damping))
    return exact_handovers(solver, out, np.ascontiguousarray(ps[:, -1]), np.ascontiguousarray(rs[:, -1]))


def exact_handovers(
    solver: PoseSolver, out: np.ndarray, end_pos: np.ndarray, end_rot: np.ndarray
) -> np.ndarray:
    """Sampled joint paths ``out`` (n, M, n_target) [rad] with each last configuration solved
    exactly for its hand-over pose (``end_pos`` (n, 3) [m], ``end_rot`` (n, 3, 3); the uncertainty
    check's configurations), from the linearised one, then clipped to the joint limits."""
    ends = PathSolution.empty(out.shape[0], out.shape[2])
    solver.follow(end_rot, end_pos, SolveSteps.seeded(out[:, -1], solver.max_iter), ends)
    out[:, -1] = ends.q
    return np.clip(out, solver.lo, solver.hi)


def check_pair(source: Robot, target: Robot) -> None:
    """Refuse a target arm that is not placed in ``source``'s scene (``[placement] source``)."""
    p = target.settings.placement
    if p is None:
        raise InfeasibleError(
            f"robot '{target.settings.name}' has no [placement] in {target.settings.path.name}: it cannot "
            f"execute robot '{source.settings.name}''s motion through the gripper"
        )
    if p.source not in (source.settings.name, str(source.settings.path), source.settings.path.stem):
        raise InfeasibleError(
            f"robot '{target.settings.name}' is placed in the scene of '{p.source}', not of "
            f"'{source.settings.name}'"
        )
