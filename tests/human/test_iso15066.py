"""ISO/TS 15066 limits (ipromp_pin.human.iso15066): S_p of clause 5.5.4, v_max = F / sqrt(mu k) of
Annex A with the reduced mass, and the robot's effective mass 1 / (u^T J M^-1 J^T u) from
Pinocchio's CRBA and the point Jacobian."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.human.iso15066 import (
    arm_mass_matrix,
    effective_mass_kg,
    max_contact_speed_m_s,
    point_effective_mass_kg,
    protective_distance_m,
    reduced_mass_kg,
    speed_bound_any_robot_m_s,
)
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.human_settings import REGION_LIMITS, HumanSettings


def test_protective_separation_distance_is_the_sum_of_its_terms():
    s = HumanSettings(
        speed_m_s=1.6,
        reaction_time_s=0.1,
        stopping_time_s=0.3,
        intrusion_m=0.02,
        human_uncertainty_m=0.05,
        robot_uncertainty_m=0.01,
    )
    # S_h = 1.6 (0.1 + 0.3), S_r = 0.5 * 0.1, S_s = 0.5 * 0.3 / 2, C + Z_d + Z_r = 0.08
    assert protective_distance_m(0.5, s) == pytest.approx(0.64 + 0.05 + 0.075 + 0.08)
    assert protective_distance_m(-1.0, s) == pytest.approx(0.64 + 0.08)  # moving away: v_r = 0


def test_contact_speed_limit_equals_the_annex_a_formula_for_the_hand():
    hand = REGION_LIMITS["hand"]
    assert (hand.force_n, hand.spring_n_m, hand.mass_kg) == (140.0, 75e3, 0.6)  # Tables A.2, A.3
    m_r = 3.0
    mu = 1.0 / (1.0 / 0.6 + 1.0 / 3.0)
    assert reduced_mass_kg(0.6, m_r) == pytest.approx(mu)
    assert max_contact_speed_m_s(hand, m_r, "quasi_static") == pytest.approx(140.0 / math.sqrt(mu * 75e3))
    assert max_contact_speed_m_s(hand, m_r, "transient") == pytest.approx(280.0 / math.sqrt(mu * 75e3))
    # a heavier robot lowers the limit toward the bound of an infinitely heavy one
    assert max_contact_speed_m_s(hand, 1e9) == pytest.approx(speed_bound_any_robot_m_s(hand), rel=1e-6)
    assert max_contact_speed_m_s(hand, 1.0) > max_contact_speed_m_s(hand, 10.0)


def test_effective_mass_of_a_hand_made_case():
    # two prismatic joints along x and y with masses 2 and 5 kg: M = diag(2, 5), J = [[1, 0], [0, 1], [0, 0]]
    mass = np.diag([2.0, 5.0])
    jac = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    assert effective_mass_kg(mass, jac, [1.0, 0.0, 0.0]) == pytest.approx(2.0)
    assert effective_mass_kg(mass, jac, [0.0, 1.0, 0.0]) == pytest.approx(5.0)
    # 45 degrees: 1 / (0.5 / 2 + 0.5 / 5)
    assert effective_mass_kg(mass, jac, [1.0, 1.0, 0.0]) == pytest.approx(1.0 / (0.25 + 0.1))
    assert effective_mass_kg(mass, jac, [0.0, 0.0, 1.0]) == math.inf  # a direction the joints cannot move
    assert effective_mass_kg(mass, jac, [1.0, 0.0, 0.0], payload_mass_kg=0.5) == pytest.approx(2.5)


def test_effective_mass_of_baxter_matches_the_inverse_formula():
    robot = load_robot("baxter_left")
    q = np.array([0.3, -0.5, 0.1, 1.2, -0.2, 0.8, 0.0])
    model, data = robot.model, robot.model.createData()
    full = robot.full_configuration(q)
    pin.framesForwardKinematics(model, data, full)
    frame = robot.ee_frame_id
    point = data.oMf[frame].translation
    jac = pin.computeFrameJacobian(model, data, full, frame, pin.LOCAL_WORLD_ALIGNED)[:3, robot.arm_v_index]
    m = arm_mass_matrix(robot, q)
    np.testing.assert_allclose(m, m.T)
    u = np.array([1.0, 0.3, -0.2]) / np.linalg.norm([1.0, 0.3, -0.2])
    expected = 1.0 / (u @ jac @ np.linalg.inv(m) @ jac.T @ u)
    parent = model.frames[frame].parentJoint
    got = point_effective_mass_kg(robot, q, parent, point, u)
    assert got == pytest.approx(expected, rel=1e-9)
    assert 0.5 < got < 30.0  # a plausible arm


def test_the_arm_models_inertia_is_the_full_models_arm_block():
    from ipromp_pin.human.iso15066 import arm_mass_matrices

    robot = load_robot("baxter_left")
    q = np.array([[0.3, -0.5, 0.1, 1.2, -0.2, 0.8, 0.0], [0.0, 0.2, -0.4, 0.5, 0.3, -0.6, 1.0]])
    fast = arm_mass_matrices(robot, q)
    for i in range(2):
        np.testing.assert_allclose(fast[i], arm_mass_matrix(robot, q[i]), atol=1e-10)
