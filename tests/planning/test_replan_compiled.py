"""The closed loop's retargeting (ReplanTransfer) with the compiled inverse kinematics equals it with
Pinocchio's solver, the reference: the same start, and re-plan after re-plan the same fitted reference
motion of the executing arm and the same residuals, on every shipped placed arm."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.motion.retarget import ReferenceMotion
from ipromp_pin.planning.transfer import ReplanTransfer
from ipromp_pin.promp.basis import GaussianBasis
from ipromp_pin.promp.compiled import use_kernels
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import Robot, load_robot

BASIS = GaussianBasis(31)


def references(shifts: list[float]) -> list[ReferenceMotion]:
    """A synthetic Baxter demo on the model's basis, its end moved by ``shift`` [rad] per joint (the
    prediction changing from re-plan to re-plan)."""
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=0).all_demos()[0]
    z = np.linspace(0.0, 1.0, len(demo.t))
    phi = np.exp(-0.5 * (z[:, None] - BASIS.centres) ** 2 / BASIS.width**2)
    out = []
    for shift in shifts:
        q = demo.groups["robot"] + shift * z[:, None]
        w = np.linalg.solve(phi.T @ phi + 1e-6 * np.eye(BASIS.n_basis), phi.T @ q)
        n = q.shape[1]
        duration = float(demo.t[-1] - demo.t[0]) * (1.0 + shift)
        out.append(ReferenceMotion(w.T, BASIS.centres, BASIS.width, np.ones(n), np.zeros(n), duration))
    return out


def replans(backend: str, source: Robot, target: Robot, refs: list[ReferenceMotion]) -> list:
    with use_kernels(backend):
        transfer = ReplanTransfer(source, target)
        q_now = transfer.start(refs[0].evaluate(np.array([0.0]), order=0)[0][0])
        return [q_now] + [transfer.reference(ref, q_now, 0.3 * ref.duration_s) for ref in refs]


@pytest.mark.parametrize("target", ["panda", "ur5", "xarm7", "kinova_jaco2"])
def test_every_re_plan_is_the_same_with_the_compiled_kernels(target):
    refs = references([0.0, 0.02, 0.05, -0.03, 0.08])
    # built apart from load_robot's cache (which keeps the 8 last robots of the session)
    source, arm = load_robot("baxter_left", cache=False), load_robot(target, cache=False)
    ref, new = replans("numpy", source, arm, refs), replans("numba", source, arm, refs)
    np.testing.assert_allclose(new[0], ref[0], rtol=0, atol=1e-9)  # the start configuration
    for (m_ref, how_ref), (m_new, how_new) in zip(ref[1:], new[1:], strict=True):
        assert how_new.reached == how_ref.reached
        assert how_ref.reached  # every one of these re-plans reaches its hand-over
        np.testing.assert_allclose(m_new.weights, m_ref.weights, rtol=0, atol=1e-9)
        assert how_new.handover_residual_mm == pytest.approx(how_ref.handover_residual_mm, abs=1e-9)
        assert how_new.handover_residual_deg == pytest.approx(how_ref.handover_residual_deg, abs=1e-9)
        assert how_new.max_path_residual_mm == pytest.approx(how_ref.max_path_residual_mm, abs=1e-9)
