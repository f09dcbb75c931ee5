"""Hostile objects files (issue of 2026-12-04, round 3): an inertia symmetric only to rounding is
symmetrised before Pinocchio sees it, one that is not symmetric, not positive definite or violates
the triangle inequality is refused; shape keys are known or refused with a suggestion; masses,
sizes and inertias lie in plausible ranges."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import RobotError
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.dynamics import ArmDynamics
from ipromp_pin.robot.objects import load_objects


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _file(tmp_path, body: str):
    f = tmp_path / "objects.toml"
    f.write_text(f"[t]\nholder = 'robot_gives'\n{body}\n")
    return f


def _refused(tmp_path, body: str, field: str) -> str:
    f = _file(tmp_path, body)
    with pytest.raises(RobotError) as exc:
        load_objects(f)
    msg = str(exc.value)
    assert msg.startswith(f"{f}: field '{field}': ") and "\n" not in msg, msg
    return msg


def test_an_inertia_asymmetric_by_rounding_is_symmetrised_and_pinocchio_takes_it(tmp_path, robot):
    body = "mass_kg = 0.3\ninertia_kg_m2 = [[1e-3, 1e-13, 0.0], [0.0, 2e-3, 0.0], [0.0, 0.0, 2.5e-3]]"
    obj = load_objects(_file(tmp_path, body)).for_task("t")
    assert obj is not None
    np.testing.assert_array_equal(obj.inertia_kg_m2, obj.inertia_kg_m2.T)
    dyn = ArmDynamics(robot)
    dyn.payload_model(obj)  # Pinocchio refuses a matrix that is not exactly symmetric
    tau = dyn.torques(np.zeros((1, 7)), payload=obj)
    assert np.all(np.isfinite(tau))


@pytest.mark.parametrize(
    ("matrix", "problem"),
    [
        ("[[1e-3, 1e-4, 0.0], [0.0, 2e-3, 0.0], [0.0, 0.0, 2.5e-3]]", "symmetric"),
        ("[[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 3e-3]]", "triangle inequality"),
        ("[[1e-3, 0.0, 0.0], [0.0, -1e-3, 0.0], [0.0, 0.0, 1e-3]]", "positive definite"),
        ("[[5.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 5.0]]", "plausible range"),
    ],
)
def test_an_impossible_inertia_is_refused(tmp_path, matrix, problem):
    msg = _refused(tmp_path, f"mass_kg = 0.3\ninertia_kg_m2 = {matrix}", "t.inertia_kg_m2")
    assert problem in msg, msg


def test_a_massless_object_with_an_inertia_is_refused(tmp_path):
    body = "mass_kg = 0.0\ninertia_kg_m2 = [[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-3]]"
    assert "massless" in _refused(tmp_path, body, "t.inertia_kg_m2")


@pytest.mark.parametrize(
    ("shape", "field", "hint"),
    [
        ("{ kind = 'cylinder', radius_m = 0.01, length_m = 0.5, axsi = 'y' }", "t.shape.axsi", "axis"),
        ("{ kind = 'box', size = [0.1, 0.1, 0.1] }", "t.shape.size", "size_m"),
        ("{ knid = 'box', size_m = [0.1, 0.1, 0.1] }", "t.shape.knid", "kind"),
        ("{ kind = 'box', size_m = [0.1, 0.1, 0.1], radius_m = 0.1 }", "t.shape.radius_m", None),
    ],
)
def test_a_shape_key_that_is_not_known_is_refused(tmp_path, shape, field, hint):
    msg = _refused(tmp_path, f"mass_kg = 0.3\nshape = {shape}", field)
    assert "unknown key" in msg
    if hint:
        assert f"did you mean '{hint}'?" in msg


def test_a_task_key_typo_gets_a_suggestion(tmp_path):
    msg = _refused(tmp_path, "mass_kg = 0.3\ncom = [0.0, 0.0, 0.1]", "t.com")
    assert "did you mean 'com_m'?" in msg


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("mass_kg = 1e6", "t.mass_kg"),
        ("mass_kg = 0.3\nshape = { kind = 'box', size_m = [0.1, 0.1, 1e3] }", "t.shape.size_m"),
        ("mass_kg = 0.3\nshape = { kind = 'cylinder', radius_m = 1e-9, length_m = 0.5 }", "t.shape.radius_m"),
    ],
)
def test_implausible_masses_and_sizes_are_refused(tmp_path, body, field):
    assert "plausible range" in _refused(tmp_path, body, field)


def test_a_schema_version_typo_is_refused(tmp_path):
    f = tmp_path / "objects.toml"
    f.write_text("schema_verison = 1\n[t]\nmass_kg = 0.3\nholder = 'robot_gives'\n")
    with pytest.raises(RobotError, match=r"field 'schema_verison': .*did you mean 'schema_version'\?"):
        load_objects(f)
