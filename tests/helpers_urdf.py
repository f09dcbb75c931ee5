"""An arm's written trajectory re-evaluated independently of the package: read from trajectory.csv,
judged against the arm's URDF and SRDF through Pinocchio (limits, self-collision, torques); and an
arm's settings placed out of reach.

The URDF is parsed as it is: a continuous joint is Pinocchio's (cos, sin) joint without position
limits (the package's model bounds it, ``ipromp_pin.robot.model.CONTINUOUS_RANGE_RAD``; here it is
only checked to be finite)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pinocchio as pin

from ipromp_pin.robot import load_robot_settings

ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def written_joints(path: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (N,) [s], positions and velocities (N, J) of trajectory.csv."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    q = np.array([[float(r[f"q.{n}"]) for n in names] for r in rows])
    qd = np.array([[float(r[f"qd.{n}"]) for n in names] for r in rows])
    return t, q, qd


class UrdfArm:
    """A shipped arm's URDF model (not the package's robot model) and its arm joints' indices."""

    def __init__(self, name: str) -> None:
        self.settings = s = load_robot_settings(name)
        self.model = pin.buildModelFromUrdf(str(s.urdf_path))
        self.names = list(s.arm_joints)
        joints = [self.model.joints[self.model.getJointId(n)] for n in self.names]
        self.idx_q = [j.idx_q for j in joints]
        self.idx_v = [j.idx_v for j in joints]
        self.continuous = [j.nq == 2 for j in joints]  # (cos, sin) joints: no position limits

    def assert_within_limits(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Positions within the URDF's limits (continuous joints: finite), speeds within its velocity
        limits."""
        m = self.model
        assert np.all(np.isfinite(q))
        for k, (iq, cont) in enumerate(zip(self.idx_q, self.continuous, strict=True)):
            if not cont:
                assert np.all(q[:, k] >= m.lowerPositionLimit[iq]) and np.all(
                    q[:, k] <= m.upperPositionLimit[iq]
                )
        assert np.all(np.abs(qd) <= m.velocityLimit[self.idx_v] + 1e-9)

    def full(self, q: np.ndarray) -> np.ndarray:
        """Full configurations (N, nq): the arm's joints ``q`` (N, J), the settings' fixed joints."""
        m = self.model
        full = np.tile(pin.neutral(m), (len(q), 1))
        for k, (iq, cont) in enumerate(zip(self.idx_q, self.continuous, strict=True)):
            if cont:
                full[:, iq], full[:, iq + 1] = np.cos(q[:, k]), np.sin(q[:, k])
            else:
                full[:, iq] = q[:, k]
        for name, value in self.settings.fixed_joints.items():
            full[:, m.joints[m.getJointId(name)].idx_q] = value
        return full

    def assert_torques_within(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, step: int = 5) -> None:
        """Torques of the arm alone (no object) from finite-difference accelerations, at every
        ``step``-th sample, within the URDF's effort limits."""
        model = self.model
        full = self.full(q)
        data = model.createData()
        qdd = np.gradient(qd, t, axis=0)
        effort = model.effortLimit[self.idx_v]
        for k in range(0, len(t), step):
            v = np.zeros(model.nv)
            a = np.zeros(model.nv)
            v[self.idx_v], a[self.idx_v] = qd[k], qdd[k]
            tau = pin.rnea(model, data, full[k], v, a)[self.idx_v]
            assert np.all(np.abs(tau) <= effort), (k, tau)

    def assert_no_self_collision(self, full: np.ndarray, step: int = 3) -> None:
        """No contact of the URDF's collision geometry (the SRDF's disabled pairs and the settings'
        ``[checks] disabled_pairs`` removed) at every ``step``-th configuration."""
        s, m = self.settings, self.model
        geom = pin.buildGeomFromUrdf(m, str(s.urdf_path), pin.COLLISION, package_dirs=list(s.package_dirs))
        geom.addAllCollisionPairs()
        pin.removeCollisionPairs(m, geom, str(s.srdf_path))
        listed = {frozenset(p) for p in s.disabled_pairs}
        g = geom.geometryObjects
        for cp in list(geom.collisionPairs):
            if frozenset(m.frames[g[k].parentFrame].name for k in (cp.first, cp.second)) in listed:
                geom.removeCollisionPair(cp)
        data, gdata = m.createData(), pin.GeometryData(geom)
        for k in range(0, len(full), step):
            assert not pin.computeCollisions(m, data, geom, gdata, full[k], True), k


def panda_out_of_reach(folder: Path) -> Path:
    """The Panda's settings with its base placed where it reaches nothing of the recordings' scene."""
    text = (ROBOTS / "panda.toml").read_text()
    start, end = text.index("\n[placement]") + 1, text.index("[fixed_joints]")
    far = folder / "panda_far.toml"
    far.write_text(
        text[:start] + '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]\n\n' + text[end:]
    )
    return far
