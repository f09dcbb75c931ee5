"""The robot's collision geometry as capsules (ipromp_pin.human.robot_capsules): each capsule holds
its geometry, the vectorised forward kinematics and point velocities equal Pinocchio's."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ipromp_pin.human.geometry import segment_closest_points
from ipromp_pin.human.robot_capsules import (
    arm_kinematics,
    fit_robot_capsules,
    point_jacobians,
    point_velocities,
)
from ipromp_pin.robot import load_robot


def test_capsules_hold_their_geometry_and_follow_pinocchio():
    robot = load_robot("baxter_left")
    caps = fit_robot_capsules(robot)
    assert caps.n_capsules > 5 and "left_gripper_base_link_0" in caps.names
    rng = np.random.default_rng(3)
    q = rng.uniform(robot.lower_rad, robot.upper_rad, size=(4, robot.n_joints))
    qd = rng.normal(size=q.shape)
    origins, axes, a, b = arm_kinematics(caps, q)
    model, data = robot.model, robot.model.createData()
    cmodel, _ = robot.collision()
    cdata = cmodel.createData()
    for i in range(q.shape[0]):
        full = robot.full_configuration(q[i])
        v = np.zeros(model.nv)
        v[robot.arm_v_index] = qd[i]
        pin.forwardKinematics(model, data, full, v)
        pin.updateGeometryPlacements(model, data, cmodel, cdata)
        for k, j in enumerate(robot.arm_joint_ids):
            np.testing.assert_allclose(origins[i, k], data.oMi[int(j)].translation, atol=1e-9)
        for m, name in enumerate(caps.names):
            obj = cmodel.geometryObjects[cmodel.getGeometryId(name)]
            placement = cdata.oMg[cmodel.getGeometryId(name)]
            geom = obj.geometry
            if type(geom).__name__ == "Cylinder":  # points on the cylinder's rim lie in the capsule
                ang = np.linspace(0, 2 * np.pi, 12)
                local = [
                    (geom.radius * np.cos(t), geom.radius * np.sin(t), z * geom.halfLength)
                    for t in ang
                    for z in (-1, 1)
                ]
            else:  # box corners
                h = np.asarray(geom.halfSide)
                local = [h * (2 * np.array(s) - 1) for s in np.ndindex(2, 2, 2)]
            pts = np.array([placement.act(np.asarray(p, dtype=float)) for p in local])
            _, _, d = segment_closest_points(a[i, m], b[i, m], pts, pts)
            assert np.all(d <= caps.radius_m[m] + 1e-9), name
        # the velocity of the gripper capsule's end point equals Pinocchio's Jacobian times qd
        m = caps.names.index("left_gripper_base_link_0")
        jid = int(robot.arm_joint_ids[caps.anchor[m]])
        pin.computeJointJacobians(model, data, full)
        jac = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)
        lever = a[i, m] - data.oMi[jid].translation
        expected = jac[:3] @ v + np.cross(jac[3:] @ v, lever)
        got = point_velocities(
            origins[i : i + 1], axes[i : i + 1], qd[i : i + 1], a[i, m][None], caps.anchor[[m]]
        )
        np.testing.assert_allclose(got[0], expected, atol=1e-9)
        pj = point_jacobians(origins[i : i + 1], axes[i : i + 1], a[i, m][None], caps.anchor[[m]])
        np.testing.assert_allclose(pj[0] @ qd[i], expected, atol=1e-9)
