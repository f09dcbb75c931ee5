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

    PYTHONPATH=. python benchmarks/handover_geometry.py [../shared/datasets/handover_20171128]

``--smoke``: the synthetic part only (no shared dataset, seconds).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ipromp_pin.data import ROBOT, Dataset
from ipromp_pin.human import HumanMotion
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.kinematics import ee_positions, gripper_kinematics
from ipromp_pin.robot.recordings import read_recordings


def geometry(ds: Dataset, robot: object, tracked: bool) -> dict[str, np.ndarray]:
    """Per demo (N, 3) [m]: gripper - torso, gripper - head, hand start - torso, hand end - gripper,
    gripper, torso."""
    fk = gripper_kinematics(robot).fk  # type: ignore[arg-type]
    settings = robot.settings.human  # type: ignore[attr-defined]
    keys = ("g_torso", "g_head", "h0_torso", "h1_g", "gripper", "torso")
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
    }
    for key, label in labels.items():
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


def main() -> None:
    robot = load_robot("baxter_left")
    if "--smoke" not in sys.argv:
        root = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/datasets/handover_20171128")
        recorded = read_recordings(root, robot)
        show(f"recorded ({root.name}, tracked torso)", geometry(recorded, robot, True))
        robot_constants(recorded, robot)
    show("synthetic (seed 0, assumed human)", geometry(make_synthetic_dataset(seed=0), robot, False))


if __name__ == "__main__":
    main()
