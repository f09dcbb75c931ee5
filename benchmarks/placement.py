"""Where to place another arm in the scene of Baxter's recordings: the reachability study behind the
default ``[placement]`` of ``robots/panda.toml``, ``robots/ur5.toml`` and ``robots/xarm7.toml``.

The hand-over poses are Baxter's gripper poses (forward kinematics of ``robots/baxter_left.toml``) at
the last joint sample of every demo: the built-in synthetic demos (seed 0, 3 tasks x 20) and the shared
recordings given on the command line. For each arm, every base position of a grid (yaw 0: the arm faces
the human, like Baxter) is scored on every third pose by the fraction reached (gripper position within
1 mm and orientation within 0.5 deg, :mod:`ipromp_pin.robot.arm_transfer`) and the median smallest
joint-limit margin of the solutions (a fraction of the joint's range); the best grid position and the
settings' own placement are then measured on every pose. Last, the time to retarget a synthetic demo's
whole path (:func:`~ipromp_pin.robot.transfer_path`, median over demos).

    PYTHONPATH=. python benchmarks/placement.py [../shared/datasets/chen2017_handover \
        ../shared/datasets/handover_20171128]

``--smoke``: six synthetic poses, two grid positions, the Panda only (seconds).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from ipromp_pin.data import ROBOT
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import Robot, build_robot, load_robot, load_robot_settings, transfer_path
from ipromp_pin.robot.arm_transfer import TOL_M, TOL_RAD, PoseSolver, gripper_poses
from ipromp_pin.robot.recordings import read_recordings
from ipromp_pin.robot.settings import Placement

ARMS = ("panda", "ur5", "xarm7")
GRID_X = (0.1, 0.2, 0.3, 0.4)
GRID_Y = (0.0, 0.2, 0.35)
GRID_Z = (-0.3, -0.1, 0.1)


def handover_configurations(baxter: Robot, datasets: list[str], smoke: bool) -> np.ndarray:
    """Baxter's joint angles (N, 7) [rad] at the end of every demo."""
    demos = make_synthetic_dataset().all_demos()
    for path in datasets:
        demos += read_recordings(path, baxter).all_demos()
    ends = np.array([d.groups[ROBOT][-1] for d in demos])
    return ends[:6] if smoke else ends


def placed(name: str, xyz: tuple[float, float, float]) -> Robot:
    """The arm of settings ``name`` at base position ``xyz`` [m] (yaw 0), kinematics only."""
    s = load_robot_settings(name)
    assert s.placement is not None
    moved = dataclasses.replace(s, placement=Placement(s.placement.source, np.array(xyz), np.zeros(3)))
    return build_robot(moved, collision=False)


def reach(arm: Robot, poses: list) -> tuple[float, float, float]:
    """Fraction of ``poses`` reached, the median limit margin and the largest position residual [mm]
    of the reached ones."""
    solver = PoseSolver(arm)
    ok, margins, residual = 0, [], 0.0
    for pose in poses:
        q, ep, er, _ = solver.first(pose, None)
        if ep <= TOL_M and er <= TOL_RAD:
            ok += 1
            margins.append(solver.margin(q))
            residual = max(residual, ep * 1e3)
    return ok / len(poses), float(np.median(margins)) if margins else 0.0, residual


def study(name: str, baxter: Robot, poses: list, smoke: bool) -> None:
    """The grid on every third pose, then the best and the settings' placement on every pose."""
    grid = [(x, y, z) for x in GRID_X for y in GRID_Y for z in GRID_Z]
    grid = grid[:2] if smoke else grid
    subset = poses[::3]
    scored = [(reach(placed(name, xyz), subset)[:2], xyz) for xyz in grid]
    (frac, margin), best = max(scored)
    print(
        f"{name}: best grid position {best} m on {len(subset)} poses: {frac:.1%} reached, margin {margin:.3f}"
    )
    own = load_robot_settings(name).placement
    assert own is not None
    for label, xyz in (("best grid", best), ("settings", tuple(float(v) for v in own.xyz_m))):
        f, m, r = reach(placed(name, xyz), poses)
        print(f"{name} {label} {xyz}: {f:.1%} of {len(poses)} hand-over poses reached, "
              f"median margin {m:.3f}, largest residual {r:.4f} mm")  # fmt: skip


def timing(baxter: Robot, smoke: bool) -> None:
    """Median time to retarget a synthetic demo's whole path to each arm."""
    demos = make_synthetic_dataset().all_demos()[:: (20 if smoke else 4)]
    for name in ARMS[:1] if smoke else ARMS:
        arm = load_robot(name)
        ms, samples = [], []
        for d in demos:
            t0 = time.perf_counter()
            transfer_path(baxter, arm, d.groups[ROBOT])
            ms.append((time.perf_counter() - t0) * 1e3)
            samples.append(d.n_samples)
        n = int(np.median(samples))
        print(f"{name}: retarget a whole path ({n} samples): median {np.median(ms):.1f} ms")


def main() -> None:
    smoke = "--smoke" in sys.argv
    datasets = [a for a in sys.argv[1:] if not a.startswith("--") and Path(a).is_dir()]
    baxter = load_robot("baxter_left")
    ends = handover_configurations(baxter, datasets, smoke)
    poses = gripper_poses(baxter, ends)
    print(f"hand-over poses: {len(poses)} (synthetic{' + ' + ', '.join(datasets) if datasets else ''})")
    for name in ARMS[:1] if smoke else ARMS:
        study(name, baxter, poses, smoke)
    timing(baxter, smoke)


if __name__ == "__main__":
    main()
