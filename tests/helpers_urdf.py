"""An arm's written trajectory re-evaluated independently of the package's checks: read from
trajectory.csv, judged against the arm's URDF and SRDF through Pinocchio (limits, self-collision,
torques) by :class:`ipromp_pin.evaluation.independent.UrdfArm` (the class ``evaluate --robot NAME``
re-evaluates every plan with); and an arm's settings placed out of reach.

The URDF is parsed as it is: a continuous joint is Pinocchio's (cos, sin) joint without position
limits (the package's model bounds it, ``ipromp_pin.robot.model.CONTINUOUS_RANGE_RAD``; here it is
only checked to be finite)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ipromp_pin.evaluation import independent

ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def written_joints(path: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (N,) [s], positions and velocities (N, J) of trajectory.csv."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    q = np.array([[float(r[f"q.{n}"]) for n in names] for r in rows])
    qd = np.array([[float(r[f"qd.{n}"]) for n in names] for r in rows])
    return t, q, qd


class UrdfArm(independent.UrdfArm):
    """The package's independent URDF model of a shipped arm, with assertions."""

    def assert_within_limits(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Positions within the URDF's limits (continuous joints: finite), speeds within its velocity
        limits."""
        excess, ratio = self.limit_excess(q, qd)
        assert excess == 0.0 and ratio <= 1.0 + 1e-9, (excess, ratio)

    def assert_torques_within(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, step: int = 5) -> None:
        """Torques of the arm alone (no object) from finite-difference accelerations, at every
        ``step``-th sample, within the URDF's effort limits."""
        ratios = self.torque_ratios(t, q, qd, 0.0, step)
        assert np.all(ratios <= 1.0), ratios

    def assert_no_self_collision(self, full: np.ndarray, step: int = 3) -> None:
        """No contact of the URDF's collision geometry (the SRDF's disabled pairs and the settings'
        ``[checks] disabled_pairs`` removed) at every ``step``-th configuration of the full
        configurations ``full`` (N, nq)."""
        assert self.collisions_full(full, step) == 0


def panda_out_of_reach(folder: Path) -> Path:
    """The Panda's settings with its base placed where it reaches nothing of the recordings' scene."""
    text = (ROBOTS / "panda.toml").read_text()
    start, end = text.index("\n[placement]") + 1, text.index("[fixed_joints]")
    far = folder / "panda_far.toml"
    far.write_text(
        text[:start] + '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]\n\n' + text[end:]
    )
    return far
