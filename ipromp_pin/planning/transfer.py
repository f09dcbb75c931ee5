"""A plan for an arm other than the one the model was trained on: the prediction's joint paths are
retargeted through the gripper (:mod:`ipromp_pin.robot.arm_transfer`) before they are timed and
checked on that arm.

:func:`source_robot` finds the model's robot: the arm itself when the model predicts its joints,
else the ``[placement] source`` of its settings (the robot of the recordings, in whose base frame the
arm is placed). :func:`retarget_prediction` turns the predicted mean path and the sampled paths into
the arm's joint paths, with the inverse kinematics' residuals (:class:`Retargeting`); where a
6-joint arm meets the hand-over pose in several configurations, :func:`kindest_to_human` prefers the
path that keeps clear of the human's body and is expected to take the least time.
:class:`ReplanTransfer` does it for every re-plan of the closed loop: the predicted reference motion
(:class:`~ipromp_pin.motion.retarget.ReferenceMotion`) becomes the executing arm's.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..data import GRIPPER
from ..exceptions import ModelError, UnreachableError
from ..motion.retarget import ReferenceMotion
from ..promp import IProMP
from ..robot import Robot, TransferredPath, load_robot, transfer_path, transfer_samples
from ..robot.arm_chain import chain_placements
from ..robot.arm_transfer import (
    SCORED_SAMPLES,
    TOL_M,
    TOL_RAD,
    TRACK_ITERATIONS,
    PathSolution,
    PoseSolver,
    Preference,
    SolveSteps,
    check_pair,
    follow_pose_path,
    follow_pose_samples,
    kindest_start,
)
from ..safety import CheckContext, CheckSuite
from ..safety.separation import SeparationCheck
from ..shipped import DEFAULT_ROBOT
from ..signals.gripper import gripper_positions, gripper_rotations


@dataclass(frozen=True)
class Retargeting:
    """How a plan's joint paths came from another robot's prediction.

    Attributes:
        source: The robot whose joints the model predicts (e.g. Baxter's left arm); for a model of
            gripper poses, the robot in whose base frame they are (the scene's).
        target: The arm that executes the plan.
        path: The mean path on the executing arm, with its residuals.
        ms: Wall time of the retargeting in [ms].
        from_poses: The model predicts the gripper pose path itself (no source joints).
    """

    source: Robot
    target: Robot
    path: TransferredPath
    ms: float
    from_poses: bool = False

    @property
    def reached(self) -> bool:
        """Whether the executing arm reaches the predicted hand-over pose."""
        return self.path.reached

    def to_dict(self) -> dict:
        """The report's ``retarget`` entry (JSON-serialisable)."""
        return {
            "source_robot": self.source.settings.name,
            "source_path": "gripper_pose" if self.from_poses else "joints",
            "reached": self.reached,
            "ik_residual_mm": round(self.path.handover_residual_mm, 4),
            "ik_residual_deg": round(self.path.handover_residual_deg, 4),
            "max_path_residual_mm": round(self.path.max_path_residual_mm, 4),
            "ms": round(self.ms, 3),
        }


def predicts_gripper(model: IProMP) -> bool:
    """Whether ``model``'s robot side is a gripper pose path (the ``gripper`` group), not joints."""
    return bool(model.groups_[-1] == GRIPPER)


def arm_for(model: IProMP, robot: str | Path | Robot | None, how: str) -> str | Path | Robot:
    """The arm that executes ``model``: ``robot``, or when None the default (Baxter's left arm) for a
    model of joints; a model of gripper poses names no arm, so none is chosen for it.

    Raises:
        ModelError: ``robot`` is None and the model predicts a gripper pose path (``how``: how to name
            the arm, e.g. ``"--robot NAME"``).
    """
    if robot is not None:
        return robot
    if predicts_gripper(model):
        raise ModelError(
            f"the model predicts a gripper pose path, not a robot's joints: name the arm that executes it "
            f"with {how} (e.g. panda, ur5, xarm7, kinova_jaco2, baxter_left)"
        )
    return DEFAULT_ROBOT


def scene_robot(robot: Robot) -> Robot:
    """The robot in whose base frame (the scene frame) a gripper pose path is given: ``robot``'s
    ``[placement] source``, or ``robot`` itself when it has no placement (it stands at the scene's
    origin, as Baxter's left arm for the shipped data)."""
    placement = robot.settings.placement
    return robot if placement is None else load_robot(placement.source)


def model_robot_names(model: IProMP, robot: Robot) -> tuple[str, ...]:
    """The model's robot joints as ``robot``'s model names (through its recorded names)."""
    recorded = robot.settings.recorded_names
    return tuple(recorded.get(n, n) for n in model.joint_names_)


def source_robot(model: IProMP, robot: Robot) -> Robot | None:
    """The robot whose joints ``model`` predicts when it is not ``robot`` (None: ``robot`` itself):
    the ``[placement] source`` of ``robot``'s settings.

    A model of gripper poses (:func:`predicts_gripper`) has no joints: its source is always the scene's
    robot (:func:`scene_robot`), ``robot`` itself when unplaced, and every plan is retargeted.

    Raises:
        ModelError: the model predicts neither ``robot``'s joints nor its placement source's.
    """
    if predicts_gripper(model):
        return scene_robot(robot)
    if model_robot_names(model, robot) == robot.joint_names or robot.settings.placement is None:
        return None  # the arm's own model, or no other arm to take it from (check_model_joints says why)
    source = load_robot(robot.settings.placement.source)
    if model_robot_names(model, source) != source.joint_names:
        raise ModelError(
            f"the model predicts joints {list(model.joint_names_)}: neither robot '{robot.settings.name}''s "
            f"nor its placement source '{source.settings.name}''s {list(source.settings.recorded_arm_joints)}"
        )
    return source


CLEARANCE_TIE_M = 0.01
"""Candidate paths whose smallest clearance from the body is within this [m] of the best one's count
as equally clear (:func:`kindest_to_human`)."""


POSE_DOF = 6
"""Joints of an arm that meets a gripper pose in a few isolated configurations (elbow up or down, wrist
flipped, ...): only such an arm chooses among them (:func:`kindest_to_human`). A redundant arm meets
it along a continuum, of which the seeds' solutions are arbitrary points: choosing among them by the
rough time estimate changed 29 of 90 one-shot Panda plans on handover_20171128, 19 of which then
arrived later (without :data:`FIRST_PATH_ADVANTAGE`), and with that margin still made the Panda's
median arrival on chen2017_handover 0.16 s later (one-shot, 5 folds, 20 % observed); it keeps its
first solution, drawn toward the middle of its joint ranges."""

FIRST_PATH_ADVANTAGE = 0.8
"""Another candidate path is preferred to the first (the seeds' first solution: the one from the
middle of the joint ranges) only when it is expected to take less than this fraction of its time:
the time is a rough estimate."""


def kindest_to_human(suite: CheckSuite, context: CheckContext, t_s: np.ndarray) -> Preference | None:
    """Scores an arm's candidate paths (S, K, n_joints) [rad] toward one hand-over, given at K of the
    path's samples (their indices (K,) into ``t_s``, the samples' times (M,) [s]), against the
    human's body as ``suite``'s ``human_clearance`` check knows it in ``context``. A path whose
    smallest clearance from the body outside the hand is more than :data:`CLEARANCE_TIE_M` below the
    largest scores -inf; the others score minus the time they are expected to take: the longer of
    the time their joints need at their velocity and acceleration limits and the time the
    contact-speed limits ask for (the largest approach speed / limit within the protective
    separation distance at that timing, over ``1 - speed_margin``), the first path's times
    :data:`FIRST_PATH_ADVANTAGE`. None: the suite has no such check or it does not apply, or the arm
    is redundant (more joints than :data:`POSE_DOF`)."""
    check = suite.get("human_clearance")
    if not isinstance(check, SeparationCheck) or not check.applies(context):
        return None
    robot = check.robot
    if robot.n_joints > POSE_DOF:  # a continuum of solutions: the seeds' are arbitrary points of it
        return None
    analyser, human = check.analyser, check.human(context)
    vel, acc = robot.velocity_rad_s, robot.settings.acceleration_rad_s2
    keep = 1.0 - robot.settings.human.speed_margin
    t_s = np.asarray(t_s, dtype=float)

    def score(paths: np.ndarray, samples: np.ndarray) -> np.ndarray:
        s, k, n = paths.shape
        t = t_s[samples]
        span = float(t[-1] - t[0])
        qd = np.gradient(paths, t, axis=1) if span > 0 and k > 1 else np.zeros_like(paths)
        q = np.ascontiguousarray(paths.reshape(-1, n), dtype=float)
        sep = analyser.analyse(np.tile(t, s), q, qd.reshape(-1, n), human)
        clear = sep.clearance_m().reshape(s, k).min(axis=1)
        travel = np.abs(np.diff(paths, axis=1)).sum(axis=1)  # (S, n) [rad] per joint
        limits_s = np.maximum(travel / vel, 2.0 * np.sqrt(travel / acc)).max(axis=1)
        contact_s = span * sep.max_ratio.reshape(s, k).max(axis=1) / keep
        expected = np.maximum(limits_s, contact_s)
        expected[0] *= FIRST_PATH_ADVANTAGE  # the first candidate unless another is clearly quicker
        return np.where(clear >= clear.max() - CLEARANCE_TIE_M, -expected, -np.inf)

    return score


def start_motions(
    model: IProMP, suite: CheckSuite | None, context: CheckContext | None
) -> list[tuple[np.ndarray, Preference]]:
    """The motions a replay's arm may be asked to make from its start, to choose its start
    configuration (:meth:`ReplanTransfer.start`): per task, the model's prior mean of the robot group
    at :data:`~ipromp_pin.robot.arm_transfer.SCORED_SAMPLES` phases over the task's mean duration,
    with :func:`kindest_to_human` against the human as known before the replay (``context``'s human
    until 0 s: its first frame, growing at the human speed after; none: the assumed human). Empty
    when that preference does not apply (no human check, an arm with more joints than a pose has)."""
    if suite is None:
        return []
    context = context if context is not None else CheckContext()
    at_start = context if context.human is None else context.replace(human=context.human.until(0.0))
    z = np.linspace(0.0, 1.0, SCORED_SAMPLES)
    out = []
    for task in model.tasks_:
        mean, _, labels = model.distribution(task, z)
        cols = [i for i, label in enumerate(labels) if label.startswith(f"{model.robot_group}/")]
        duration = float(model.models_[task].alpha_mu) * float(model.duration_nominal_s_)
        prefer = kindest_to_human(suite, at_start, z * duration)
        if prefer is None:
            return []
        out.append((mean[:, cols], prefer))
    return out


def retarget_prediction(
    source: Robot,
    robot: Robot,
    q_mean: np.ndarray,
    samples: np.ndarray,
    from_poses: bool = False,
    prefer: Preference | None = None,
) -> tuple[np.ndarray, np.ndarray, Retargeting]:
    """The mean path (M, n_joints) and the sampled paths (n, M, n_joints) of ``robot`` [rad] whose
    gripper follows ``source``'s along ``q_mean`` (M, n_source) and ``samples`` (n, M, n_source);
    ``from_poses``: they are gripper pose paths (M, 7) and (n, M, 7) (x, y, z [m] and a quaternion
    qx, qy, qz, qw, renormalised here) in ``source``'s base frame, followed as they are. ``prefer``
    chooses the hand-over configuration where the arm has several (e.g. :func:`kindest_to_human`)."""
    t0 = time.perf_counter()
    if from_poses:
        if robot.settings.placement is not None:
            check_pair(source, robot)
        pm, rm = gripper_positions(q_mean), gripper_rotations(q_mean)
        path = follow_pose_path(robot, pm, rm, prefer=prefer)
    else:
        path = transfer_path(source, robot, q_mean, prefer=prefer)
    if not path.reached:  # refused: the samples are not followed either
        moved = np.broadcast_to(path.q, (samples.shape[0],) + path.q.shape).copy()
    elif from_poses:
        moved = follow_pose_samples(
            robot, gripper_positions(samples), gripper_rotations(samples), path, pm, rm
        )
    else:
        moved = transfer_samples(source, robot, samples, path, q_mean)
    ms = (time.perf_counter() - t0) * 1e3
    return path.q, moved, Retargeting(source, robot, path, ms, from_poses)


def fade_out(z: np.ndarray, z_from: float) -> np.ndarray:
    """Weights (M,) at phases ``z`` (M,): 1 up to ``z_from``, then a smoothstep down to 0 at phase 1."""
    x = np.clip((np.asarray(z, dtype=float) - z_from) / max(1.0 - z_from, 1e-9), 0.0, 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


def warped_poses(
    pos: np.ndarray, rot: np.ndarray, keep: np.ndarray, pos_offset: np.ndarray, rot_offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A gripper pose path (positions (M, 3) [m], rotations (M, 3, 3)) moved by the weights ``keep``
    (M,) of an offset: ``pos_offset`` (3,) [m] in the scene frame, ``rot_offset`` (3,) a rotation
    vector [rad] in the path's own frame."""
    turn = Rotation.from_rotvec(keep[:, None] * np.asarray(rot_offset)[None, :]).as_matrix()
    return pos + keep[:, None] * np.asarray(pos_offset)[None, :], rot @ turn


N_GRID = 41
"""Phase samples [0, 1] at which a re-plan's predicted gripper path is followed by inverse kinematics
(the executing arm's reference is fitted to them on the prediction's own basis)."""

FIT_RIDGE = 1e-8
"""Ridge of the least-squares fit of the executing arm's joint samples on the basis (conditioning
only: overlapping Gaussian bumps are nearly collinear)."""


@dataclass(frozen=True)
class ReplanRetarget:
    """How one re-plan's reference motion came from the model's robot (``replans.json``'s ``retarget``).

    Attributes:
        source: The model's robot's name.
        reached: Whether the executing arm reaches the predicted hand-over pose.
        handover_residual_mm: Gripper position residual [mm] at the hand-over of the executing arm's
            reference (its end is the inverse kinematics' hand-over solution).
        handover_residual_deg: Gripper orientation residual [deg] there.
        max_path_residual_mm: Largest gripper position residual [mm] of the executing arm's reference
            at the phase samples and halfway between them (inverse kinematics and fit on the basis
            together).
        ms: Wall time [ms] of the retargeting.
        restarted: Whether it was followed as a first re-plan from where the arm's gripper is (the
            arm had not moved and the previous re-plan was refused; the residuals are then against
            that moved path).
        from_poses: The model predicts the gripper pose path itself (no source joints).
    """

    source: str
    reached: bool
    handover_residual_mm: float
    handover_residual_deg: float
    max_path_residual_mm: float
    ms: float
    restarted: bool = False
    from_poses: bool = False

    def to_dict(self) -> dict:
        """JSON-serialisable form, with the keys of the one-shot report's ``retarget``."""
        return {
            "source_robot": self.source,
            "source_path": "gripper_pose" if self.from_poses else "joints",
            "reached": self.reached,
            "ik_residual_mm": round(self.handover_residual_mm, 4),
            "ik_residual_deg": round(self.handover_residual_deg, 4),
            "max_path_residual_mm": round(self.max_path_residual_mm, 4),
            "ms": round(self.ms, 3),
            "restarted": self.restarted,
        }


class ReplanTransfer:
    """The closed loop's retargeting through the gripper, one re-plan after the other.

    Each re-plan's reference motion of ``source``'s joints is sampled at :data:`N_GRID` phases, its
    gripper poses followed by ``target``'s inverse kinematics, and the solutions fitted on the
    reference's basis, the hand-over exactly (a least-squares fit constrained at the end): a reference
    motion of ``target``'s joints on the same timeline, with exact derivatives. The first re-plan
    follows the path from the arm's commanded configuration (at the sample nearest the re-plan's
    time, forward to the hand-over and back to the start); every later one starts each sample from
    the previous re-plan's solution at the same phase, so that consecutive re-plans stay on one
    branch of the inverse kinematics and take one or two iterations per sample. A re-plan whose
    hand-over the arm cannot reach keeps no solution (the next one starts from the last reached). An
    arm that has not moved yet after a refused re-plan restarts: the next one is followed as a first
    re-plan, its path moved to start where the arm's gripper is (``restart``).
    """

    def __init__(self, source: Robot, target: Robot, n_grid: int = N_GRID, from_poses: bool = False) -> None:
        if not from_poses or target.settings.placement is not None:
            check_pair(source, target)
        self.source = source
        self.target = target
        self.from_poses = from_poses  # the reference motion is a gripper pose path (7 channels), not joints
        self.solver = PoseSolver(target)
        self.solver.prime()  # the compiled kernels loaded before the first re-plan, not during it
        self.phase = np.linspace(0.0, 1.0, n_grid)
        self.mid = 0.5 * (self.phase[1:] + self.phase[:-1])  # where the fit's residual is measured too
        self._previous: np.ndarray | None = None  # (n_grid, n_target) the last reached solution
        self._fit: tuple[bytes, float, np.ndarray, np.ndarray, np.ndarray] | None = None

    def start(
        self, q_source: np.ndarray, motions: Sequence[tuple[np.ndarray, Preference]] = ()
    ) -> np.ndarray:
        """The arm's configuration (n_target,) [rad] whose gripper is at ``source``'s at ``q_source``
        (n_source,) [rad] (the start of a replayed demo): where the arm meets that pose in several
        configurations (a 6-joint arm), the one from which it best makes ``motions``, the source's
        motions it may be asked to follow from there (each (M, n_source) values and the preference
        scoring the arm's paths along it, :func:`start_motions`; :func:`kindest_start`), else the
        first the seeds reach.

        Raises:
            UnreachableError: the arm cannot reach that pose at its placement.
        """
        pos, rot = self._placements(np.asarray(q_source, dtype=float)[None])
        if motions:
            poses = [(*self._placements(values), prefer) for values, prefer in motions]
            chosen = kindest_start(self.solver, rot[0], pos[0], poses)
            if chosen is not None:
                return chosen
        q, err_p, err_r, _ = self.solver.first_pose(rot[0], pos[0], None)
        if not (err_p <= TOL_M and err_r <= TOL_RAD):
            raise UnreachableError(
                f"robot '{self.target.settings.name}' cannot reach the recorded start pose of "
                f"'{self.source.settings.name}''s gripper at its placement: inverse kinematics stops "
                f"{err_p * 1e3:.1f} mm and {np.degrees(err_r):.2f} deg away"
            )
        return q

    def _placements(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gripper positions (M, 3) [m] and rotations (M, 3, 3) of the source's joints
        (M, n_source) [rad], or of gripper pose values (M, 7) with ``from_poses``."""
        if not self.from_poses:
            return chain_placements(self.source, values)
        return gripper_positions(values), gripper_rotations(values)

    def _basis(self, reference: ReferenceMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The basis at the phase samples (M, K) and between them (M - 1, K), and the constrained
        fit's operator (K, M) (kept while the reference's basis stays the same)."""
        key = reference.centres.tobytes()
        if self._fit is None or self._fit[0] != key or self._fit[1] != reference.width:
            diff = self.phase[:, None] - reference.centres[None, :]
            phi = np.exp(-0.5 * diff * diff / reference.width**2)  # (M, K)
            diff = self.mid[:, None] - reference.centres[None, :]
            phi_mid = np.exp(-0.5 * diff * diff / reference.width**2)
            k, m = phi.shape[1], phi.shape[0]
            kkt = np.zeros((k + 1, k + 1))
            kkt[:k, :k] = phi.T @ phi + FIT_RIDGE * np.eye(k)
            kkt[:k, k] = kkt[k, :k] = phi[-1]
            rhs = np.zeros((k + 1, m))
            rhs[:k] = phi.T
            rhs[k, -1] = 1.0
            self._fit = (key, reference.width, phi, phi_mid, np.linalg.solve(kkt, rhs)[:k])
        return self._fit[2], self._fit[3], self._fit[4]

    def _follow(self, rot: np.ndarray, pos: np.ndarray, q_now: np.ndarray, j: int) -> PathSolution:
        """Joint samples, position and orientation errors along the poses ``rot`` (M, 3, 3), ``pos``
        (M, 3) [m]: from the previous re-plan's, else from ``q_now`` at sample ``j``."""
        m, n = pos.shape[0], self.target.n_joints
        out = PathSolution.empty(m, n)
        if self._previous is not None:
            self.solver.follow(rot, pos, SolveSteps.seeded(self._previous, TRACK_ITERATIONS), out)
            return out
        order = [j] + list(range(j + 1, m)) + list(range(j - 1, -1, -1))
        steps = SolveSteps.chained(
            order, [-1] + [i - 1 for i in order[1:] if i > j] + list(range(j, 0, -1)), n
        )
        steps.seeds[0] = q_now
        steps.max_iters[0] = self.solver.max_iter
        self.solver.follow(rot, pos, steps, out)
        return out

    def reference(
        self, reference: ReferenceMotion, q_now: np.ndarray, t_now_s: float, restart: bool = False
    ) -> tuple[ReferenceMotion | None, ReplanRetarget]:
        """``reference`` (of ``source``'s joints) as the executing arm's reference motion, from its
        commanded configuration ``q_now`` (n_target,) [rad] at ``t_now_s`` [s] on the reference's
        timeline (used by the first re-plan only), and how closely it follows (None: the arm cannot
        reach the hand-over pose; the re-plan is refused). ``restart``: follow it as a first re-plan,
        the pose path moved to start where the arm's gripper is (:func:`warped_poses`): for an arm
        that has not moved yet and whose re-plan was refused."""
        t0 = time.perf_counter()
        d = reference.duration_s
        m = self.phase.size
        z = np.concatenate([self.phase, self.mid])
        src_pos, src_rot = self._placements(reference.evaluate(z * d, order=0)[0])  # phases, then between
        j = int(np.clip(round(t_now_s / d * (m - 1)), 0, m - 1))
        if restart:
            self._previous = None
            if j < m - 1:  # from where the gripper is now, joining the predicted path by the hand-over
                now_pos, now_rot = chain_placements(self.target, np.asarray(q_now, dtype=float)[None])
                offset = Rotation.from_matrix(src_rot[j].T @ now_rot[0]).as_rotvec()
                keep = fade_out(z, self.phase[j])
                src_pos, src_rot = warped_poses(src_pos, src_rot, keep, now_pos[0] - src_pos[j], offset)
        rot, pos = np.ascontiguousarray(src_rot[:m]), np.ascontiguousarray(src_pos[:m])
        out = self._follow(rot, pos, q_now, j)
        if not out.reached(m - 1):  # the tracked branch misses: every seed
            end = self.solver.first_pose(rot[-1], pos[-1], out.q[-1])
            if end[1] <= TOL_M and end[2] <= TOL_RAD:
                out.set(m - 1, end)
                back = np.arange(m - 2, -1, -1)  # the path leads to that solution
                self.solver.follow(rot, pos, SolveSteps.chained(back, back + 1, self.target.n_joints), out)
        q, err_p, err_r = out.q, out.err[:, 0], out.err[:, 1]

        def report(reached: bool, path_mm: float) -> ReplanRetarget:
            ms = (time.perf_counter() - t0) * 1e3
            handover_deg = float(np.degrees(err_r[-1]))
            name = self.source.settings.name
            return ReplanRetarget(
                name, reached, err_p[-1] * 1e3, handover_deg, path_mm, ms, restart, self.from_poses
            )

        if not out.reached(m - 1):
            return None, report(False, float(err_p.max() * 1e3))
        self._previous = q
        phi, phi_mid, fit = self._basis(reference)
        weights = fit @ q  # (K, n)
        n = self.target.n_joints
        moved = ReferenceMotion(weights.T, reference.centres, reference.width, np.ones(n), np.zeros(n), d)
        # the residual of what the arm is commanded: at the samples and between them (the fit's)
        commanded, _ = chain_placements(self.target, np.vstack([phi @ weights, phi_mid @ weights]))
        path_mm = float(np.max(np.linalg.norm(commanded - src_pos, axis=1)) * 1e3)
        return moved, report(True, max(path_mm, err_p[-1] * 1e3))

    def why_not_reached(self, retarget: ReplanRetarget) -> str:
        """One clause: how far the executing arm stays from the re-plan's hand-over pose."""
        return (
            f"robot '{self.target.settings.name}' cannot reach the predicted hand-over pose at its "
            f"placement: inverse kinematics stops {retarget.handover_residual_mm:.1f} mm and "
            f"{retarget.handover_residual_deg:.2f} deg away (at most {TOL_M * 1e3:g} mm and "
            f"{np.degrees(TOL_RAD):g} deg)"
        )
