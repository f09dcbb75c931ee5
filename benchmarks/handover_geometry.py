"""Where the hand-over happens relative to the human's torso: the recordings against the synthetic demos.

For every demo of a dataset with a tracked skeleton (``handover_20171128``): the torso (``/torso_1``,
median of its reliable samples over the demo, :meth:`ipromp_pin.human.HumanMotion.from_demo`), the
head (``/head_1``, the same) and the recorded robot's gripper at the demo's end (forward kinematics
of the last joint sample, ``robots/baxter_left.toml``), and the human hand at the start and at the
end (the reader's ``hand_position``). Prints, in Baxter's base frame [m], the median and the 5th/
95th percentiles over the demos of the gripper relative to the torso and to the head and of the
hand's start relative to the torso.

Then the same for the built-in synthetic demos (seed 0, 3 tasks x 20), against the assumed human of
``robots/baxter_left.toml`` (``[human.assumed]``): the numbers the synthetic hand-over and the
assumed human are placed with (``ipromp_pin/readers/synthetic.py``).

Last, how fast each demo's robot path brings the arm toward the human's face (:func:`face_approach`):
the robot's joint path of the demo (smoothed over :data:`SMOOTH_S`, from where it has gone 2 % of the
way from its first to its last configuration to where it is within 2 % of the last) timed as
``ipromp-pin run`` times a plan (time-optimal, starting after :data:`OBSERVED` of the demo) and
re-timed until ``human_clearance`` and ``contact_speed`` pass against the human as known at that
time (the tracked skeleton of the recordings, the assumed human of the synthetic demos); the same
for the straight joint-space line between the path's two ends (the shape of the synthetic robot's
path); and the largest approach speed / contact-speed limit of the path at the demo's own pace.

With ``--arms panda,ur5,...``: the same per arm, each demo's recorded path retargeted through the
gripper onto the arm at its placement (:func:`~ipromp_pin.robot.transfer_path`) and judged with the
arm's own capsules, limits and human checks; a dataset without a tracked skeleton
(``chen2017_handover``) is judged against the assumed human of the arm's settings. Per arm the
own-pace ratio's most frequent limiting pairs (robot link -> body part) are printed too: which part of
the arm meets which part of the person too fast, the gripper path being the same for every arm.

    PYTHONPATH=. python benchmarks/handover_geometry.py [../shared/datasets/handover_20171128]
        [--arms baxter_left,panda,ur5,xarm7,kinova_jaco2]

``--smoke``: the synthetic part only (no shared dataset, seconds), on Baxter and the UR5.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from ipromp_pin.data import ROBOT, Dataset, Demo
from ipromp_pin.human import HumanMotion
from ipromp_pin.motion.limits import JointLimits
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.timers import PathTimer
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot, transfer_path
from ipromp_pin.robot.kinematics import ee_positions, frame_placements, gripper_kinematics
from ipromp_pin.robot.recordings import read_recordings
from ipromp_pin.safety import CheckContext, CheckReport, CheckSuite

OBSERVED = 0.2
"""Observed fraction of the demo before the robot starts (``run``'s default ``observation.ratio``)."""
SMOOTH_S = 0.06
"""Gaussian smoothing (standard deviation) of a recorded joint path, in [s]: the joint encoders' noise
would make the time-optimal timing crawl."""


def geometry(ds: Dataset, robot: object, tracked: bool) -> dict[str, np.ndarray]:
    """Per demo (N, 3) [m]: gripper - torso, gripper - head, hand start - torso, hand end - gripper,
    gripper, torso, the robot's elbow (``left_lower_elbow``) - head at the start and at the end."""
    fk = gripper_kinematics(robot).fk  # type: ignore[arg-type]
    settings = robot.settings.human  # type: ignore[attr-defined]
    keys = ("g_torso", "g_head", "h0_torso", "h1_g", "gripper", "torso", "e0_head", "e1_head")
    elbow = robot.model.getFrameId("left_lower_elbow")  # type: ignore[attr-defined]
    rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for task in ds.tasks:
        for d in ds.demos[task]:
            if tracked:
                human = HumanMotion.from_demo(d, settings)
            else:
                human = HumanMotion.assumed_human(settings, d.t, d.extras.get("hand_position"))
            assert human is not None, f"{d.source}: no skeleton"
            pos = human.positions_m
            torso = np.nanmedian(pos[:, human.frames.index("/torso_1")], axis=0)
            head = np.nanmedian(pos[:, human.frames.index("/head_1")], axis=0)
            gripper = np.asarray(fk(d.groups[ROBOT][-1:]), dtype=float).reshape(3)
            hand = d.extras.get("hand_position")
            h0 = np.asarray(hand[0], dtype=float) if hand is not None else np.full(3, np.nan)
            h1 = np.asarray(hand[-1], dtype=float) if hand is not None else np.full(3, np.nan)
            rows["g_torso"].append(gripper - torso)
            rows["g_head"].append(gripper - head)
            rows["h0_torso"].append(h0 - torso)
            rows["h1_g"].append(h1 - gripper)
            rows["gripper"].append(gripper)
            rows["torso"].append(torso)
            ends = frame_placements(robot, d.groups[ROBOT][[0, -1]], elbow)[0]  # type: ignore[arg-type]
            rows["e0_head"].append(ends[0] - head)
            rows["e1_head"].append(ends[1] - head)
    return {k: np.array(v) for k, v in rows.items()}


def show(title: str, g: dict[str, np.ndarray]) -> None:
    """Print the median and 5-95 % range per axis of every row of ``g``."""
    print(f"{title}: {len(g['torso'])} demos; median [5th, 95th percentile] per base-frame axis [m]")
    labels = {
        "torso": "torso",
        "gripper": "gripper at the end",
        "g_torso": "gripper - torso",
        "g_head": "gripper - head",
        "h0_torso": "hand at the start - torso",
        "h1_g": "hand at the end - gripper",
        "e0_head": "elbow at the start - head",
        "e1_head": "elbow at the end - head",
    }
    for key, label in labels.items():
        if np.all(np.isnan(g[key])):
            print(f"  {label:<26} not recorded")
            continue
        q = np.nanpercentile(g[key], [5, 50, 95], axis=0)
        cells = "  ".join(f"{a} {q[1, i]:+.3f} [{q[0, i]:+.3f}, {q[2, i]:+.3f}]" for i, a in enumerate("xyz"))
        print(f"  {label:<26} {cells}")
    dist = np.linalg.norm(g["g_head"], axis=1)
    print(
        f"  gripper to head distance   median {np.median(dist):.3f} m [{np.percentile(dist, 5):.3f}, "
        f"{np.percentile(dist, 95):.3f}]"
    )


def robot_constants(ds: Dataset, robot: object) -> None:
    """Print the robot constants of ``ipromp_pin/readers/synthetic.py`` measured on ``ds``: start and
    hand-over configurations, hand-over points, their spreads, the gripper's position Jacobian at the
    hand-over configurations and the regression of the hand-over configuration on the hand-over point."""
    starts = np.array([d.groups[ROBOT][0] for task in ds.tasks for d in ds.demos[task]])
    rows: dict[str, list[np.ndarray]] = {
        k: [] for k in ("q", "q_std", "point", "point_std", "jac", "reg", "res")
    }
    for task in ds.tasks:
        q = np.array([d.groups[ROBOT][-1] for d in ds.demos[task]])
        p = np.array([d.extras["endpoint_pose"][-1, :3] for d in ds.demos[task]])
        q_med = np.median(q, axis=0)
        qc, pc = q - q.mean(axis=0), p - p.mean(axis=0)
        reg = np.linalg.lstsq(pc, qc, rcond=None)[0].T  # (7, 3): configuration per point [rad/m]
        jac = np.empty((3, q.shape[1]))
        for j in range(q.shape[1]):
            dq = np.zeros(q.shape[1])
            dq[j] = 1e-6
            fwd = ee_positions(robot, (q_med + dq)[None])[0]  # type: ignore[arg-type]
            back = ee_positions(robot, (q_med - dq)[None])[0]  # type: ignore[arg-type]
            jac[:, j] = (fwd - back) / 2e-6
        rows["q"].append(q_med)
        rows["q_std"].append(q.std(axis=0))
        rows["point"].append(np.median(p, axis=0))
        rows["point_std"].append(p.std(axis=0))
        rows["jac"].append(jac)
        rows["reg"].append(reg)
        rows["res"].append((qc - pc @ reg.T).std(axis=0))
    print(f"constants of the synthetic robot ({', '.join(ds.tasks)}):")
    print(f"  START_Q_RAD {np.median(starts, axis=0).round(3).tolist()}")
    for key in ("q", "point", "jac", "reg"):
        print(f"  {key} per task {np.array(rows[key]).round(3).tolist()}")
    for key in ("q_std", "point_std", "res"):
        print(f"  {key} (mean of the tasks) {np.mean(rows[key], axis=0).round(3).tolist()}")


def _span(q: np.ndarray) -> tuple[int, int]:
    """First and last sample of the motion of joint path ``q`` (N, 7) [rad]: one sample before it has
    gone 2 % of the way from its first to its last configuration, and where it is within 2 % of the
    last."""
    f = 1.0 - np.linalg.norm(q - q[-1], axis=1) / max(float(np.linalg.norm(q[0] - q[-1])), 1e-9)
    return max(int(np.argmax(f > 0.02)) - 1, 0), int(np.argmax(f > 0.98))


def _timed(robot: object, suite: CheckSuite, path: np.ndarray, human: HumanMotion, t_obs: float) -> list:
    """``path`` (M, 7) [rad] timed like a plan from ``t_obs`` [s], re-timed until the checks pass:
    [slow-down (the duration factor), unslowed duration [s], end [s], worst contact-speed pair of the
    unslowed motion, whether it was slowed only where the checks asked (else uniformly), and the
    uniform slow-down the same checks would have asked for]."""
    ctx = CheckContext(human=human.until(t_obs))
    limits = JointLimits.from_robot(robot)  # type: ignore[arg-type]
    timer = PathTimer(path, limits, suite.timing_constraints(ctx), 100.0, t_obs, lambda _m: None)
    r = suite.retime_until_safe(timer, ctx)
    uniform = suite.retime_until_safe(lambda k: timer(k), ctx)  # a plain timer: the uniform slow-down
    m = CheckReport(suite.run(r.first.motion, ctx))["contact_speed"].measures
    pair = f"{m.link} -> {m.body_part}" if r.slowdown > 1.0 else ""  # type: ignore[attr-defined]
    return [r.slowdown, r.first.motion.duration_s, r.motion.end_s, pair, r.local, uniform.slowdown]


def _own_pace_ratio(suite: CheckSuite, demo: Demo, q: np.ndarray, human: HumanMotion) -> tuple[float, str]:
    """The largest approach speed / contact-speed limit of the joint path ``q`` (N, n_joints) [rad]
    at the demo's own pace against ``human`` (every sample known), and its pair (link -> body part)."""
    t = demo.t - demo.t[0]
    spline = CubicSpline(t, q)
    tt = np.arange(0.0, t[-1], 0.01)
    motion = Trajectory(
        tt, spline(tt), spline(tt, 1), spline(tt, 2), tuple(f"q{j}" for j in range(q.shape[1]))
    )
    m = suite.only(("contact_speed",)).run(motion, CheckContext(human=human))[0].measures
    return float(m.max_speed_ratio), f"{m.link} -> {m.body_part}"  # type: ignore[attr-defined]


def face_approach(
    ds: Dataset, robot: object, tracked: bool, every: int = 1, arm: object | None = None
) -> dict[str, list]:
    """Per demo (every ``every``-th): the recorded path and the straight joint-space line between its
    ends timed like a plan and re-timed until the human checks pass (``path``, ``line``: see
    :func:`_timed`), the path's own-pace contact-speed ratio and its pair (``pace``, ``pair``), the
    human's duration [s] (``human_s``) and the gripper's path length [m] (``gripper_m``). ``arm``:
    the paths retargeted onto that arm and judged on it (demos whose hand-over it does not reach are
    left out, counted in ``unreached``)."""
    executing = robot if arm is None else arm
    settings = executing.settings.human  # type: ignore[attr-defined]
    suite = CheckSuite.build(executing, ("human_clearance", "contact_speed"))  # type: ignore[arg-type]
    keys = ("path", "line", "pace", "pair", "human_s", "gripper_m", "unreached")
    rows: dict[str, list] = {k: [] for k in keys}
    for demo in ds.all_demos()[::every]:
        t = demo.t - demo.t[0]
        if tracked:
            human = HumanMotion.from_demo(demo, settings)
        else:
            human = HumanMotion.assumed_human(settings, t, demo.extras.get("hand_position"))
        if human is None:
            continue
        rate = (len(t) - 1) / t[-1]
        q = gaussian_filter1d(np.asarray(demo.groups[ROBOT], float), SMOOTH_S * rate, axis=0, mode="nearest")
        i0, i1 = _span(q)
        path = q[i0 : i1 + 1]
        gripper_m = float(np.linalg.norm(np.diff(ee_positions(robot, path), axis=0), axis=1).sum())  # type: ignore[arg-type]
        if arm is not None:  # the same gripper path on the arm: the whole demo's and the motion's
            moved = transfer_path(robot, arm, q)  # type: ignore[arg-type]
            if not moved.reached:
                rows["unreached"].append(demo.name)
                continue
            q, path = moved.q, moved.q[i0 : i1 + 1]
        line = path[0] + np.linspace(0.0, 1.0, len(path))[:, None] * (path[-1] - path[0])
        t_obs = OBSERVED * float(t[-1])
        rows["path"].append(_timed(executing, suite, path, human, t_obs))
        rows["line"].append(_timed(executing, suite, line, human, t_obs))
        ratio, pair = _own_pace_ratio(suite, demo, q, human)
        rows["pace"].append(ratio)
        rows["pair"].append(pair)
        rows["human_s"].append(float(t[-1]))
        rows["gripper_m"].append(gripper_m)
    return rows


def show_face(title: str, rows: dict[str, list]) -> None:
    """Print the medians and shares of :func:`face_approach`'s rows."""
    n = len(rows["human_s"])
    human_s = np.array(rows["human_s"])
    pace = np.array(rows["pace"])
    p5, p50, p95 = np.percentile(pace, [5, 50, 95])
    print(
        f"{title}: {n} demos; robot path at the demo's own pace: approach speed / contact-speed limit "
        f"median {p50:.2f} [5th {p5:.2f}, 95th {p95:.2f}], over the planning limit 0.9 in "
        f"{np.mean(pace > 0.9):.0%}; gripper path median {np.median(rows['gripper_m']):.3f} m"
    )
    top = ", ".join(f"{p} {c}" for p, c in Counter(rows["pair"]).most_common(4))
    unreached = f"; hand-over not reached in {len(rows['unreached'])}" if rows["unreached"] else ""
    print(f"  largest at the demo's own pace between: {top}{unreached}")
    for key, label in (("path", "the demo's robot path"), ("line", "straight joint line between its ends")):
        k = np.array([r[0] for r in rows[key]], dtype=float)
        base = np.array([r[1] for r in rows[key]], dtype=float)
        late = np.array([r[2] for r in rows[key]], dtype=float) - human_s
        worst = Counter(r[3] for r in rows[key] if r[3])
        top = ", ".join(f"{p} {c}" for p, c in worst.most_common(3)) or "none"
        print(
            f"  {label:<38} timed like a plan: slow-down median {np.median(k):.2f} "
            f"[95th {np.percentile(k, 95):.2f}], over 1.3x in {np.mean(k > 1.3):.0%}; unslowed "
            f"{np.median(base):.2f} s; at rest after the human's end median {np.median(late):+.2f} s, "
            f"within 0.5 s in {np.mean(late <= 0.5):.0%}; slowed by: {top}"
        )
        local = np.array([r[4] for r in rows[key]], dtype=bool)
        uniform = np.array([r[5] for r in rows[key]], dtype=float)
        print(
            f"  {'':<38} of the {np.sum(k != 1.0)} re-timed, {np.sum(local)} only where the checks ask (the "
            f"rest uniformly); uniformly throughout it would be x{np.median(uniform):.2f} median "
            f"[95th {np.percentile(uniform, 95):.2f}]"
        )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", nargs="?", default="../shared/datasets/handover_20171128")
    parser.add_argument(
        "--arms", default="", help="comma-separated robots the demos' paths are retargeted onto"
    )
    parser.add_argument("--smoke", action="store_true", help="the synthetic part only (seconds)")
    args = parser.parse_args()
    robot = load_robot("baxter_left")
    arms = [load_robot(a) for a in (args.arms or ("ur5" if args.smoke else "")).split(",") if a]
    every = 10 if args.smoke else 1
    synthetic = make_synthetic_dataset(seed=0)
    if not args.smoke:
        root = Path(args.dataset)
        recorded = read_recordings(root, robot)
        tracked = HumanMotion.from_demo(recorded.all_demos()[0], robot.settings.human) is not None
        human = "tracked" if tracked else "assumed"
        show(f"recorded ({root.name}, {human} torso)", geometry(recorded, robot, tracked))
        robot_constants(recorded, robot)
    show("synthetic (seed 0, assumed human)", geometry(synthetic, robot, False))
    print("the arm toward the face, each demo's robot path timed like a plan (module docstring):")
    if not args.smoke:
        show_face(f"recorded ({root.name}, {human} human)", face_approach(recorded, robot, tracked))
    show_face("synthetic (seed 0, assumed human)", face_approach(synthetic, robot, False, every))
    for arm in arms:
        name = arm.settings.name
        if not args.smoke:
            show_face(
                f"on {name}: recorded ({root.name}, {human} human)",
                face_approach(recorded, robot, tracked, 1, arm),
            )
        show_face(
            f"on {name}: synthetic (seed 0, assumed human)",
            face_approach(synthetic, robot, False, every, arm),
        )


if __name__ == "__main__":
    main()
