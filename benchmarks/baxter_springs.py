"""Fit Baxter's shoulder (s1) counterbalance spring from the recorded joint efforts.

Baxter reports the torque its motors deliver on /robot/joint_states (``.effort``). The URDF's
inverse dynamics (Pinocchio RNEA, :class:`ipromp_pin.robot.dynamics.ArmDynamics` without springs)
matches it within about 1 N m on every left-arm joint but s1, where the motor delivers some 25 N m
less: the springs of Baxter's shoulder carry that part of the arm's weight. This script fits the
missing torque as ``c0 + c1 * q_s1`` on every 10th joint-state sample of the chen2017_handover
recordings and prints the ``[springs]`` line of ``robots/baxter_left.toml`` with the residuals.

    PYTHONPATH=. python benchmarks/baxter_springs.py [../shared/datasets/chen2017_handover]

``--smoke``: efforts made from the URDF's RNEA minus a known spring (plus 1 N m noise) at random
poses, to check that the fit recovers it: no shared dataset, a second.
"""

from __future__ import annotations

import ast
import csv
import sys
from pathlib import Path

import numpy as np

from ipromp_pin.robot import load_robot
from ipromp_pin.robot.dynamics import ArmDynamics

JOINTS = ["left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2"]


def read_states(root: Path, step: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Positions and efforts (N, 7) of every ``step``-th full joint-state message."""
    q, effort = [], []
    for f in sorted(root.glob("*/csv/*-robot-joint_states.csv")):
        with open(f, newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if r[".name"].startswith("['head_nod'")]
        for r in rows[::step]:
            names = ast.literal_eval(r[".name"])
            pos = dict(zip(names, ast.literal_eval(r[".position"]), strict=True))
            eff = dict(zip(names, ast.literal_eval(r[".effort"]), strict=True))
            q.append([pos[n] for n in JOINTS])
            effort.append([eff[n] for n in JOINTS])
    return np.array(q), np.array(effort)


def smoke_states(dyn: ArmDynamics, n: int = 500) -> tuple[np.ndarray, np.ndarray]:
    """Random arm poses and the efforts of a known s1 spring (-40 - 25 q_s1 N m) with 1 N m noise."""
    rng = np.random.default_rng(0)
    q = rng.uniform(-0.9, 0.9, (n, len(JOINTS)))
    q[:, 1] = rng.uniform(-0.98, -0.37, n)
    effort = dyn.torques(q)
    effort[:, 1] -= -40.0 - 25.0 * q[:, 1]
    return q, effort + rng.normal(0.0, 1.0, effort.shape)


def main() -> None:
    dyn = ArmDynamics(load_robot("baxter_left"), springs=False)
    if "--smoke" in sys.argv:
        q, effort = smoke_states(dyn)
    else:
        root = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/datasets/chen2017_handover")
        q, effort = read_states(root)
    rnea = dyn.torques(q)  # the demos move slowly: gravity
    gap = rnea - effort
    print(
        f"{len(q)} samples; median |RNEA - recorded effort| per joint [N m]:",
        np.median(np.abs(gap), 0).round(2),
    )
    slope, c0 = np.polyfit(q[:, 1], gap[:, 1], 1)
    res = gap[:, 1] - (c0 + slope * q[:, 1])
    print(
        f"s1 spring torque = {c0:.2f} + {slope:.2f} * q_s1 [N m], "
        f"for q_s1 in [{q[:, 1].min():.2f}, {q[:, 1].max():.2f}]"
    )
    print(
        f"residual |.| median {np.median(np.abs(res)):.2f} N m, "
        f"95th percentile {np.percentile(np.abs(res), 95):.2f} N m"
    )
    print(f"[springs]\nleft_s1 = [{c0:.2f}, {slope:.2f}]")


if __name__ == "__main__":
    main()
