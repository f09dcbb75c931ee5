"""Hostile robot settings (issue of 2026-12-04, round 3): every table and key of a settings file is
known or refused with a "did you mean" for a near miss, and every safety value lies in a plausible
range whose source the message names; the ranges are one table in code and in docs/safety.md."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ipromp_pin.exceptions import RobotError
from ipromp_pin.robot import ROBOTS_DIR, load_robot_settings
from ipromp_pin.robot.human_settings import REGION_LIMITS
from ipromp_pin.robot.ranges import PLAUSIBLE_RANGES

LEFT = ROBOTS_DIR / "baxter_left.toml"
DOCS = Path(__file__).resolve().parents[2] / "docs" / "safety.md"


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    """The left arm's settings with one textual substitution (regex, first match, multi-line)."""
    text, n = re.subn(old, new, LEFT.read_text(), count=1, flags=re.M)
    assert n == 1, f"pattern {old!r} not found"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    return path


def _appended(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "bad.toml"
    path.write_text(LEFT.read_text() + "\n" + extra + "\n")
    return path


def _refused(path: Path, field: str) -> str:
    """The one-line error of loading ``path``, which must name the file and ``field``."""
    with pytest.raises(RobotError) as exc:
        load_robot_settings(path)
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: field '{field}': "), msg
    return msg


@pytest.mark.parametrize(
    ("old", "new", "field", "hint"),
    [
        (r"^speed_margin = 0\.1$", "speed_margn = 0.5", "iso15066.speed_margn", "speed_margin"),
        (r"^stopping_time_s = 0\.3$", "stoping_time_s = 3.0", "iso15066.stoping_time_s", "stopping_time_s"),
        (r"^speed_m_s = 1\.6$", "sped_m_s = 1.6", "human.sped_m_s", "speed_m_s"),
        (r"^max_inflation_m = ", "max_inflaton_m = ", "human.max_inflaton_m", "max_inflation_m"),
        (r"^handing_arm = ", "handing_arms = ", "human.handing_arms", "handing_arm"),
        (r"^handing_arm = \"predicted\"$", 'handing_arm = "predict"', "human.handing_arm", "predicted"),
        (r"^\[iso15066\]$", "[iso15606]", "iso15606", "iso15066"),
        (r"^\[human\]$", "[humans]", "humans", "human"),
        (r"^\[human\.assumed\]$", "[human.asumed]", "human.asumed", "assumed"),
        (r"^torso_m = ", "torso = ", "human.assumed.torso", "torso_m"),
        (r"^name = ", "nmae = ", "nmae", "name"),
        (r"^package = ", "pakage = ", "description.pakage", "package"),
        (r"^\[arm\.recorded_names\]$", "[arm.recorded_name]", "arm.recorded_name", "recorded_names"),
        (r"^frame = ", "frmae = ", "end_effector.frmae", "frame"),
        (r"^mount_offset_m = ", "mount_ofset_m = ", "calibration.mount_ofset_m", "mount_offset_m"),
        (r"^jerk_rad_s3 = ", "jerk_rad_s = ", "limits.jerk_rad_s", "jerk_rad_s3"),
        (r"^effort_margin = ", "efort_margin = ", "limits.efort_margin", "effort_margin"),
        (r"^window_s = ", "windw_s = ", "limits.demonstrated.windw_s", "window_s"),
        (r"^shape = \"box\"$", 'shap = "box"', "workspace.shap", "shape"),
        (r"^min_clearance_m = ", "min_clearence_m = ", "checks.min_clearence_m", "min_clearance_m"),
        (r"^\[springs\]$", "[spring]", "spring", "springs"),
    ],
)
def test_a_misspelt_key_or_table_is_refused_with_a_suggestion(tmp_path, old, new, field, hint):
    msg = _refused(_variant(tmp_path, old, new), field)
    assert f"did you mean '{hint}'?" in msg, msg


def test_a_misspelt_region_table_and_an_unknown_region_are_refused(tmp_path):
    msg = _refused(_appended(tmp_path, "[iso15066.region.face]\nforce_n = 65.0"), "iso15066.region")
    assert "did you mean 'regions'?" in msg
    msg = _refused(_appended(tmp_path, "[iso15066.regions.fase]\nforce_n = 65.0"), "iso15066.regions.fase")
    assert "did you mean 'face'?" in msg
    msg = _refused(
        _appended(tmp_path, "[iso15066.regions.face]\nforce = 60.0"), "iso15066.regions.face.force"
    )
    assert "did you mean 'force_n'?" in msg


def test_a_key_with_nothing_near_lists_the_known_ones(tmp_path):
    msg = _refused(_variant(tmp_path, r"^min_clearance_m = ", "zzz = 1\nmin_clearance_m = "), "checks.zzz")
    assert "did you mean" not in msg and "known: " in msg and "min_clearance_m" in msg


@pytest.mark.parametrize(
    ("edit", "field", "source"),
    [
        (("append", "[iso15066.regions.face]\nforce_n = 1e9"), "iso15066.regions.face.force_n", "Table A.2"),
        (("append", "[iso15066.regions.hand]\nforce_n = 141.0"), "iso15066.regions.hand.force_n",
         "Table A.2"),
        (("append", "[iso15066.regions.hand]\ntransient_factor = 1e6"),
         "iso15066.regions.hand.transient_factor", "A.3.2"),
        (("append", "[iso15066.regions.face]\ntransient_factor = 2.0"),
         "iso15066.regions.face.transient_factor", "A.3.2"),
        (("append", "[iso15066.regions.chest]\nspring_n_mm = 1.0"), "iso15066.regions.chest.spring_n_mm",
         "Table A.3"),
        (("append", "[iso15066.regions.hand]\nmass_kg = 0.01"), "iso15066.regions.hand.mass_kg", "Table A.3"),
        ((r"^reaction_time_s = 0\.1$", "reaction_time_s = 0.0"), "iso15066.reaction_time_s", "cycle"),
        ((r"^stopping_time_s = 0\.3$", "stopping_time_s = 0.0"), "iso15066.stopping_time_s", "decelerat"),
        ((r"^speed_m_s = 1\.6$", "speed_m_s = 1e-300"), "human.speed_m_s", "ISO 13855"),
        ((r"^speed_m_s = 1\.6$", "speed_m_s = 30.0"), "human.speed_m_s", "ISO 13855"),
        ((r"^speed_margin = 0\.1$", "speed_margin = 0.9"), "iso15066.speed_margin", "speed_margin_cv"),
        ((r"^intrusion_m = 0\.0$", "intrusion_m = 5.0"), "iso15066.intrusion_m", "ISO 13855"),
        ((r"^human_uncertainty_m = 0\.05$", "human_uncertainty_m = 3.0"), "iso15066.human_uncertainty_m",
         "tracker"),
        ((r"^robot_uncertainty_m = 0\.01$", "robot_uncertainty_m = 1.0"), "iso15066.robot_uncertainty_m",
         "calibration"),
        ((r"^max_inflation_m = 0\.15$", "max_inflation_m = 0.0"), "human.max_inflation_m", "0.07 m"),
        ((r"^speed_m_s = 1\.6$", "speed_m_s = 1.6\nradii_m = { head = 5.0 }"), "human.radii_m.head",
         "95th-percentile"),
        ((r"^speed_m_s = 1\.6$", "speed_m_s = 1.6\nmin_separation_m = 4.0"), "human.min_separation_m",
         "reach"),
        ((r"^effort_margin = 0\.1$", "effort_margin = 0.95"), "limits.effort_margin", "inertias"),
        ((r"^position_margin_rad = .*$", "position_margin_rad = 2.0"), "limits.position_margin_rad",
         "demonstrations"),
        ((r"^min_clearance_m = .*$", "min_clearance_m = 5.0"), "checks.min_clearance_m", "clearance"),
        ((r"^facing_deg = .*$", "facing_deg = 1e9"), "human.assumed.facing_deg", "turn"),
    ],
)  # fmt: skip
def test_a_safety_value_outside_its_plausible_range_is_refused_naming_range_and_source(
    tmp_path, edit, field, source
):
    path = _appended(tmp_path, edit[1]) if edit[0] == "append" else _variant(tmp_path, *edit)
    msg = _refused(path, field)
    assert "plausible range" in msg and source in msg, msg


def test_stricter_region_values_are_kept(tmp_path):
    s = load_robot_settings(
        _appended(tmp_path, "[iso15066.regions.hand]\nforce_n = 70.0\nspring_n_mm = 150\nmass_kg = 4.4")
    )
    hand = s.human.regions["hand"]
    assert (hand.force_n, hand.spring_n_m, hand.mass_kg) == (70.0, 150e3, 4.4)


@pytest.mark.parametrize("name", ["baxter_left", "baxter_right", "panda"])
def test_the_shipped_settings_are_within_their_ranges(name):
    s = load_robot_settings(name)
    assert s.human.speed_m_s == 1.6 and s.human.regions == REGION_LIMITS


def test_an_unknown_body_part_radius_names_the_file(tmp_path):
    msg = _refused(_variant(tmp_path, r"^speed_m_s = 1\.6$", "speed_m_s = 1.6\nradii_m = { hed = 0.1 }"),
                   "human.radii_m.hed")  # fmt: skip
    assert "did you mean 'head'?" in msg and "human settings" not in msg


def _docs_rows() -> dict[str, list[str]]:
    rows = {}
    for line in DOCS.read_text().splitlines():
        m = re.match(r"^\| `([^`]+)` \|(.*)\|$", line)
        if m:
            rows[m.group(1)] = [c.strip() for c in m.group(2).split("|")]
    return rows


def test_every_range_is_in_the_docs_table_with_its_numbers_and_source():
    rows = _docs_rows()
    missing = [k for k in PLAUSIBLE_RANGES if k not in rows]
    assert not missing, f"ranges not in docs/safety.md: {missing}"
    for key, rng in PLAUSIBLE_RANGES.items():
        cells = rows[key]
        assert cells[0] == rng.text(), (key, cells[0], rng.text())
        assert cells[1] == rng.source, key
        assert rng.source, key
