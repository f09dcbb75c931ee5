"""The shipped report schemas hold exactly the checks' entries as the checks declare them
(ipromp_pin.safety.schema): a new check or measure cannot be written without its schema, and every
measure is described with its unit."""

from __future__ import annotations

import dataclasses

import jsonschema
import numpy as np

from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.robot import load_robot
from ipromp_pin.safety import CHECKS, CheckContext, CheckSuite
from ipromp_pin.safety.schema import checks_schema
from ipromp_pin.schemas import load_schema


def test_the_shipped_schemas_are_the_checks_own():
    expected = checks_schema(CHECKS)
    report = load_schema("report")["properties"]
    assert report["feasibility"]["properties"]["checks"] == expected
    assert report["retreat"]["properties"]["checks"] == expected
    replans = load_schema("replans")["properties"]["replans"]["items"]["properties"]
    assert replans["checks"] == expected
    replay = dict(load_schema("replay_report")["properties"]["checks"])
    assert replay.pop("description") and replay == expected


def test_every_measure_is_described():
    for check in CHECKS:
        props = checks_schema([check])["properties"][check.name]["properties"]
        for f in dataclasses.fields(check.measures_type):
            assert props[f.name].get("description"), (check.name, f.name)


def test_real_verdicts_validate_and_a_stray_field_is_refused():
    robot = load_robot("baxter_left")
    q = np.linspace(
        [-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661],
        [-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274],
        50,
    )
    qd = np.gradient(q, 0.02, axis=0)
    motion = Trajectory(
        0.5 + np.arange(50) * 0.02, q, qd, np.gradient(qd, 0.02, axis=0), tuple(robot.joint_names)
    )
    report = CheckSuite.build(robot).report(motion, CheckContext())
    doc = report.to_dict()
    assert set(doc) == {c.name for c in CHECKS}
    validator = jsonschema.Draft202012Validator(checks_schema(CHECKS))
    validator.validate(doc)
    doc["joint_limits"]["surprise"] = 1
    assert not validator.is_valid(doc)
