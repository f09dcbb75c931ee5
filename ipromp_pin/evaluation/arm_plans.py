"""The evaluation of an arm executing a model of another robot (issue 37), and of any arm's one-shot
plans: what ``evaluate --robot NAME`` adds to every trial and cell.

An arm with a ``[placement]`` executes a model of its placement's source robot (Baxter's left arm,
whose recordings train it): the recordings are read with the source's joints
(:func:`recordings_robot`), the model is fitted on them, and every test plan is retargeted through the
gripper (:mod:`ipromp_pin.planning.transfer`) and planned and checked on the arm.

* **One-shot** (:class:`TrialPlanner`): every test demo's one-shot plan as ``run`` makes it (predict
  from the window, retarget, time, check, re-time) on the arm, the checks knowing the human as
  observed until the window's end (tracked, or the assumed human). Scored against the recording
  (:class:`PlannedTrial`): the inverse kinematics' reach and residuals, pass or the failed checks
  (``unreachable``: refused before timing), the hand-over error (the arm's gripper at rest vs the
  recorded gripper at the demo's end, both in the scene frame) and the arrival delay (the planned
  gripper's arrival vs the recorded one's, :func:`~.scoring.arrival_time`).
* **Closed loop** (:func:`replay_arm_measures`): the replay's re-plans' residuals and refusals by
  reason.
* **Both**: every trajectory that would be executed is re-evaluated independently
  (:mod:`.independent`: the arm's URDF limits, torques with the true task's object, self-collision)
  and its human checks are judged against the whole recorded human
  (:func:`~.scoring.human_measures`); ``violations`` names what either found (:func:`violations_of`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from ..data import ROBOT, Demo
from ..exceptions import InfeasibleError, UnreachableError
from ..human import HumanMotion
from ..motion.trajectory import Trajectory
from ..planning.closed_loop import ClosedLoopResult
from ..planning.one_shot import plan
from ..promp import IProMP
from ..robot import Robot, ee_positions, load_robot, transfer_path
from ..robot.objects import ObjectTable
from ..safety import HUMAN_CHECKS, CheckContext, CheckSuite
from .cells import median
from .independent import TORQUE_FRACTION, UrdfArm
from .scoring import arrival_time, human_measures, peak_torque_ratio, recorded_scores
from .windows import FitWindow


def recordings_robot(robot: Robot) -> Robot | None:
    """The robot whose joints the recordings (and the model) hold when ``robot`` executes them
    retargeted: its ``[placement] source``; None for an arm without placement (its own)."""
    placement = robot.settings.placement
    return None if placement is None else load_robot(placement.source)


def human_of(demo: Demo, robot: Robot) -> HumanMotion:
    """The demo's human over the whole recording: its tracked skeleton, else ``robot``'s assumed
    standing human (its hand following the demo's ``hand_position`` when there is one)."""
    settings = robot.settings.human
    human = HumanMotion.from_demo(demo, settings)
    if human is None:
        human = HumanMotion.assumed_human(settings, demo.t, demo.extras.get("hand_position"))
    return human


def violations_of(judged: dict, min_separation_m: float = 0.0) -> list[str]:
    """What a re-evaluation (:meth:`TrajectoryJudge.judge`'s fields) found violated: ``limits``
    (beyond the URDF's position or velocity limits), ``torques`` (over :data:`TORQUE_FRACTION` of the
    effort limits, from the URDF or the joint-torque check with the true task's object),
    ``self_collision``, ``contact_speed`` (control samples beyond the contact-speed limit against the
    recorded human; the checks' planning margin below it is not a violation) and ``human_contact``
    (the robot at or within ``min_separation_m`` [m] of the body outside the hand)."""
    out = []
    if judged["position_excess_rad"] > 1e-9 or judged["velocity_ratio"] > 1.0 + 1e-9:
        out.append("limits")
    torque = judged.get("object_torque_ratio")
    if judged["torque_ratio"] > TORQUE_FRACTION or (torque is not None and torque > TORQUE_FRACTION):
        out.append("torques")
    if judged["self_collisions"]:
        out.append("self_collision")
    if judged.get("contact_speed_violations"):
        out.append("contact_speed")
    separation = judged.get("human_min_separation_m")
    if separation is not None and separation <= min_separation_m:
        out.append("human_contact")
    return out


class TrajectoryJudge:
    """Re-evaluates a trajectory of ``robot`` after the fact (see the module docstring): the URDF
    model is built in each process on first use."""

    def __init__(self, robot: Robot, objects: ObjectTable | None) -> None:
        self.robot = robot
        self.objects = objects
        self._arm: UrdfArm | None = None
        self._humans: CheckSuite | None = None
        self._torques: CheckSuite | None = None

    def judge(self, trajectory: Trajectory, demo: Demo, human: HumanMotion | None) -> dict:
        """The findings on ``trajectory`` (times on the demo's clock) for the true task of ``demo``:
        the independent ones (:class:`~.independent.Findings`), the joint-torque check's peak ratio
        with the true task's object, the human checks against ``human`` (the whole recording), and
        ``violations``: every name found."""
        if self._arm is None:
            self._arm = UrdfArm(self.robot.settings.path)
            self._humans = CheckSuite.build(self.robot).only(HUMAN_CHECKS)
            self._torques = CheckSuite.build(self.robot).only(["joint_torques"])
        assert self._humans is not None and self._torques is not None
        payload = self.objects.for_task(demo.task) if self.objects is not None else None
        mass = 0.0 if payload is None else float(payload.mass_kg)
        found = self._arm.judge(trajectory.t_s, trajectory.q, trajectory.qd, mass)
        torque = peak_torque_ratio(self._torques, trajectory, demo.task, self.objects)
        out = {**found.to_dict(), "object_torque_ratio": round(torque, 6) if np.isfinite(torque) else None}
        if human is not None and self._humans.checks:
            measures = human_measures(trajectory, human, self._humans)
            out["human_passed"] = measures.passed
            out["contact_speed_violations"] = measures.contact_speed_violations
            out["human_min_separation_m"] = measures.min_separation_m
            # where the closest pair met: the arm's link, the body part, when [s] on the demo's clock
            out["human_closest"] = [measures.link, measures.body_part, measures.t_s]
        return out | {"violations": violations_of(out, self.robot.settings.human.min_separation_m)}


@dataclass
class PlannedTrial:
    """A test demo's one-shot plan on the executing arm, scored against the recording.

    Attributes:
        passed: Whether the plan passed (known task, every check, the timing's verification).
        failures: The failed checks (``unknown_task``, a check's name, ``timing``), or ``unreachable``
            (refused before timing) or ``infeasible`` (the path cannot be timed).
        retargeted: Whether the plan was retargeted from the model's robot.
        reached: Whether the arm reached the predicted hand-over pose (None: not retargeted).
        ik_residual_mm: Gripper position residual [mm] at the hand-over (None: not retargeted).
        ik_residual_deg: Gripper orientation residual [deg] there.
        max_path_residual_mm: Largest position residual [mm] along the path (reached only).
        handover_error_cm: The planned gripper at rest vs the recorded gripper at the demo's end,
            [cm] in the scene frame (None: no trajectory).
        arrival_delay_s: The planned gripper's arrival minus the recorded one's, [s].
        slowdown: The checks' slow-down (1: none).
        judged: The re-evaluation of the trajectory (:meth:`TrajectoryJudge.judge`; None: none).
    """

    passed: bool
    failures: list[str] = field(default_factory=list)
    retargeted: bool = False
    reached: bool | None = None
    ik_residual_mm: float | None = None
    ik_residual_deg: float | None = None
    max_path_residual_mm: float | None = None
    handover_error_cm: float | None = None
    arrival_delay_s: float | None = None
    slowdown: float = 1.0
    judged: dict | None = None

    @property
    def passed_with_violation(self) -> bool:
        """A plan that passed although its re-evaluation found a violation."""
        return bool(self.passed and self.judged is not None and self.judged["violations"])

    def to_dict(self) -> dict:
        """JSON-serialisable form (floats rounded)."""
        out = asdict(self)
        return {k: round(v, 4) if isinstance(v, float) else v for k, v in out.items()}


def recorded_arrival_s(demo: Demo, recorded: Robot) -> float:
    """When the recorded gripper arrives, [s] from the demo's start (:func:`~.scoring.arrival_time`)."""
    return arrival_time(demo.t - demo.t[0], ee_positions(recorded, demo.groups[ROBOT]))


class TrialPlanner:
    """Plans every test demo's one-shot hand-over on ``robot`` (see the module docstring).

    Args:
        robot: The executing arm.
        source: The robot whose joints the model predicts when it is not ``robot``
            (:func:`recordings_robot`; None: ``robot`` itself).
        objects: The tasks' objects (payload of the torque check and of the re-evaluation).
        control_rate_hz: Output sampling rate [Hz].
    """

    def __init__(
        self,
        robot: Robot,
        source: Robot | None = None,
        objects: ObjectTable | None = None,
        control_rate_hz: float = 100.0,
    ) -> None:
        self.robot = robot
        self.source = source
        self.objects = objects
        self.control_rate_hz = control_rate_hz
        self.judge = TrajectoryJudge(robot, objects)
        self._suite: CheckSuite | None = None

    @property
    def recorded(self) -> Robot:
        """The robot of the recordings."""
        return self.robot if self.source is None else self.source

    def suite(self) -> CheckSuite:
        """Every check of ``run`` (built once per process)."""
        if self._suite is None:
            self._suite = CheckSuite.build(self.robot)
        return self._suite

    def plan_trial(self, model: IProMP, demo: Demo, window: FitWindow | float) -> PlannedTrial:
        """The one-shot plan of ``demo`` from its ``window``, scored (:class:`PlannedTrial`)."""
        window = FitWindow.of(window)
        observation = window.cut(demo, list(model.observe_))
        human = human_of(demo, self.robot)
        end = float(observation.t[-1])
        context = CheckContext(human=human.until(end), objects=self.objects)
        suite = self.suite()
        suite.reset()
        retargeted = self.source is not None
        try:
            result = plan(
                model, self.robot, observation, suite, context,
                control_rate_hz=self.control_rate_hz, check_joints=False, source=self.source,
            )  # fmt: skip
        except UnreachableError:
            return self.unreachable(model, observation)
        except InfeasibleError:
            return PlannedTrial(passed=False, failures=["infeasible"], retargeted=retargeted)
        out = PlannedTrial(passed=result.passed, failures=list(result.failures), retargeted=retargeted)
        if result.retarget is not None:
            how = result.retarget.to_dict()
            out.reached = bool(how["reached"])
            out.ik_residual_mm, out.ik_residual_deg = how["ik_residual_mm"], how["ik_residual_deg"]
            out.max_path_residual_mm = how["max_path_residual_mm"]
        out.handover_error_cm = recorded_scores(result, demo, self.robot, self.source).handover_error_cm
        traj = result.trajectory
        arrival = arrival_time(traj.t_s, ee_positions(self.robot, traj.q))
        out.arrival_delay_s = arrival - recorded_arrival_s(demo, self.recorded)
        out.slowdown = float(result.slowdown)
        out.judged = self.judge.judge(traj, demo, human)
        return out

    def unreachable(self, model: IProMP, observation: Demo) -> PlannedTrial:
        """A plan refused before timing: the arm cannot reach the predicted hand-over pose (its
        residuals from the inverse kinematics' seeds)."""
        assert self.source is not None, "only a retargeted plan is refused as unreachable"
        prediction = model.predict(observation)
        end = transfer_path(self.source, self.robot, np.asarray(prediction.q_mean)[-1:])  # type: ignore[union-attr]
        return PlannedTrial(
            passed=False,
            failures=["unreachable"],
            retargeted=True,
            reached=False,
            ik_residual_mm=end.handover_residual_mm,
            ik_residual_deg=end.handover_residual_deg,
        )


def plan_summary(plans: Sequence[PlannedTrial], robot: str, source: str | None) -> dict:
    """A cell's one-shot plans on the executing arm (``Cell.plans``): how many, reached (of the
    retargeted), passed, refused by failed check, passed with a violation; the largest residuals
    where reached; the medians over the passed plans of the hand-over error and arrival delay."""
    moved = [p for p in plans if p.retargeted]
    reached = [p for p in moved if p.reached]
    passed = [p for p in plans if p.passed]
    refused = Counter(f for p in plans if not p.passed for f in p.failures)
    found = Counter(v for p in passed if p.judged is not None for v in p.judged["violations"])

    def largest(key: str, rows: Sequence[PlannedTrial]) -> float | None:
        values = [getattr(p, key) for p in rows if getattr(p, key) is not None]
        return max(values) if values else None

    judged = [p.judged for p in plans if p.judged is not None]
    return {
        "robot": robot,
        "source_robot": source,
        "plans": len(plans),
        "retargeted": len(moved),
        "reached": len(reached),
        "passed": len(passed),
        "refused": dict(sorted(refused.items())),
        "passed_with_violation": sum(p.passed_with_violation for p in plans),
        "violations_found": dict(sorted(found.items())),
        "max_ik_residual_mm": largest("ik_residual_mm", reached),
        "max_ik_residual_deg": largest("ik_residual_deg", reached),
        "max_path_residual_mm": largest("max_path_residual_mm", reached),
        "handover_error_cm": median([p.handover_error_cm for p in passed]),
        "arrival_delay_s": median([p.arrival_delay_s for p in passed]),
        "max_torque_ratio": max((j["torque_ratio"] for j in judged), default=None),
    }


def refusal_kind(reason: str, checks: dict[str, dict]) -> list[str]:
    """The names a refused re-plan is counted under: its failed checks, else the first word of its
    reason (``unreachable``, ``not re-targeted``, ``prediction failed``, ...)."""
    failed = [name for name, v in checks.items() if v.get("status") == "fail"]
    return failed or [reason.split(":")[0].strip() or "refused"]


def replay_arm_measures(result: ClosedLoopResult, judged: dict | None) -> dict:
    """A closed-loop replay's re-plans on the executing arm: retargeted and reached counts, the
    largest residuals over the committed re-plans, the refusals by reason, and the re-evaluation of
    the commanded trajectory (``judged``, :meth:`TrajectoryJudge.judge`)."""
    moved = [r for r in result.replans if r.retarget is not None]
    kept = [r.retarget for r in moved if r.committed and r.retarget is not None]
    refused = Counter(k for r in result.replans if not r.committed for k in refusal_kind(r.reason, r.checks))

    def largest(key: str) -> float | None:
        return max(float(d[key]) for d in kept) if kept else None

    return {
        "retargeted": len(moved),
        "reached": sum(bool(r.retarget and r.retarget["reached"]) for r in moved),
        "max_ik_residual_mm": largest("ik_residual_mm"),
        "max_ik_residual_deg": largest("ik_residual_deg"),
        "max_path_residual_mm": largest("max_path_residual_mm"),
        "refused": dict(sorted(refused.items())),
        "judged": judged,
    }


def replay_arm_summary(rows: Sequence[dict | None], robot: str, source: str | None) -> dict:
    """A cell's closed-loop replays on the executing arm (``ClosedLoopCell.arm``): ``rows`` are the
    trials' :func:`replay_arm_measures` (None: the replay was refused before the loop, the arm
    cannot reach the recorded start)."""
    done = [r for r in rows if r is not None]

    def largest(key: str) -> float | None:
        values = [r[key] for r in done if r[key] is not None]
        return max(values) if values else None

    refused: Counter[str] = Counter()
    for r in done:
        refused.update(r["refused"])
    with_violation = [r for r in done if r["judged"] is not None and r["judged"]["violations"]]
    found = Counter(v for r in with_violation for v in r["judged"]["violations"])
    return {
        "robot": robot,
        "source_robot": source,
        "replays": len(rows),
        "unreachable_start": len(rows) - len(done),
        "retargeted_replans": sum(r["retargeted"] for r in done),
        "reached_replans": sum(r["reached"] for r in done),
        "max_ik_residual_mm": largest("max_ik_residual_mm"),
        "max_ik_residual_deg": largest("max_ik_residual_deg"),
        "max_path_residual_mm": largest("max_path_residual_mm"),
        "refused_replans": dict(sorted(refused.items())),
        "replays_with_violation": len(with_violation),
        "violations_found": dict(sorted(found.items())),
    }
