"""Where to place another arm in the scene of Baxter's recordings: the reachability study behind the
default ``[placement]`` of ``robots/panda.toml``, ``ur5.toml``, ``xarm7.toml`` and
``kinova_jaco2.toml``, with the package's own search (:mod:`ipromp_pin.robot.reachability`, which
``ipromp-pin place`` runs).

The hand-over poses are Baxter's gripper poses (forward kinematics of ``robots/baxter_left.toml``) at
the last joint sample of every demo: the built-in synthetic demos (seed 0, 3 tasks x 20) and the shared
recordings given on the command line. For each arm:

1. the study: every base position of a grid (yaw 0: the arm faces the human, like Baxter; ``STUDY_GRID``)
   scored on a third of the poses (evenly spread) by the fraction reached (gripper position within
   1 mm and orientation within 0.5 deg) and the median smallest joint-limit margin of the solutions (a
   fraction of the joint's range), the best and the settings' own placement measured on every pose;
2. the settings' placement on each dataset's poses;
3. ``ipromp-pin place``'s search (positions and yaws of its default region, refined) on every pose.

Last, the time to retarget a synthetic demo's whole path (:func:`~ipromp_pin.robot.transfer_path`,
median over demos).

    PYTHONPATH=. python benchmarks/placement.py [../shared/datasets/chen2017_handover \
        ../shared/datasets/handover_20171128]

``--smoke``: six synthetic poses, two grid positions, the Panda only, no search (seconds).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from ipromp_pin.data import ROBOT
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import Robot, load_robot, load_robot_settings, transfer_path
from ipromp_pin.robot.reachability import PlacementGrid, ReachTest, handover_poses, search_placement
from ipromp_pin.robot.recordings import read_recordings

ARMS = ("panda", "ur5", "xarm7", "kinova_jaco2")
STUDY_GRID = PlacementGrid(x_m=(0.1, 0.2, 0.3, 0.4), y_m=(0.0, 0.2, 0.35), z_m=(-0.3, -0.1, 0.1))
SMOKE_GRID = PlacementGrid(x_m=(0.1, 0.4), y_m=(0.0,), z_m=(0.1,))


def dataset_poses(baxter: Robot, datasets: list[str], smoke: bool) -> dict[str, list[pin.SE3]]:
    """Hand-over poses per dataset name (the synthetic demos first)."""
    out = {"synthetic": handover_poses(baxter, make_synthetic_dataset().all_demos())}
    for path in datasets:
        out[Path(path).name] = handover_poses(baxter, read_recordings(path, baxter).all_demos())
    return {"synthetic": out["synthetic"][:6]} if smoke else out


def study(name: str, poses: dict[str, list[pin.SE3]], smoke: bool) -> None:
    """The grid study, the settings' placement per dataset and ``place``'s search."""
    settings = load_robot_settings(name)
    every = [p for ps in poses.values() for p in ps]
    t0 = time.perf_counter()
    grid = SMOKE_GRID if smoke else STUDY_GRID
    found = search_placement(settings, every, grid, subset_size=max(len(every) // 3, 1), refinements=0)
    where = tuple(round(float(v), 3) for v in found.suggested.xyz_m)
    print(f"{name} study grid (yaw 0): best {where} m: {found.at_suggested.summary()} "
          f"({found.n_candidates} positions, {time.perf_counter() - t0:.1f} s)")  # fmt: skip
    test = ReachTest(settings)
    own = tuple(float(v) for v in test.settings.placement.xyz_m)  # type: ignore[union-attr]
    for label, ps in [*poses.items(), ("all", every)]:
        r = test.reach(ps)
        assert r is not None
        print(f"{name} settings {own} on {label}: {r.summary()}")
    if smoke:
        return
    t0 = time.perf_counter()
    found = search_placement(settings, every)
    p, seconds = found.suggested, time.perf_counter() - t0
    where = ", ".join(f"{v:.3f}" for v in p.xyz_m)
    print(f"{name} place search: ({where}) m, yaw {p.rpy_deg[2]:.1f} deg: {found.at_suggested.summary()} "
          f"({found.n_candidates} placements, {seconds:.1f} s)")  # fmt: skip


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
    poses = dataset_poses(baxter, datasets, smoke)
    print("hand-over poses: " + ", ".join(f"{k} {len(v)}" for k, v in poses.items()))
    for name in ARMS[:1] if smoke else ARMS:
        study(name, poses, smoke)
    timing(baxter, smoke)


if __name__ == "__main__":
    main()
