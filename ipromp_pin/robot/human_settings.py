"""The human side of a robot settings file: the ``[human]`` and ``[iso15066]`` tables, validated.

``[human]`` holds the body model's parameters (radii overrides per body part, the speed at which an
unseen body part may move, the cap of that inflation) and the placement of the *assumed* human used
when a recording has no tracked skeleton; ``[iso15066]`` holds the parameters of the protective
separation distance (ISO/TS 15066:2016 clause 5.5.4) and overrides of the Annex A body-region limits.
Every value is checked here (finite, positive where it must be); the defaults and their sources are
described in ``docs/safety.md`` and in the shipped ``robots/*.toml``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import RobotError

ISO13855_HUMAN_SPEED_M_S = 1.6
"""Walking speed of a person approaching a machine, ISO 13855:2010 clause 6.2.3 (K = 1600 mm/s for
distances over 500 mm): the human speed of S_h unless measured."""


@dataclass(frozen=True)
class RegionLimit:
    """ISO/TS 15066:2016 Annex A values of one body region.

    Attributes:
        force_n: Maximum permissible quasi-static contact force in [N] (Table A.2).
        transient_factor: Multiplier of ``force_n`` for a transient contact (Annex A.3.2: up to 2;
            1 where the settings keep transient contacts at the quasi-static value, e.g. the head).
        spring_n_m: Effective spring constant k in [N/m] (Table A.3, given there in N/mm).
        mass_kg: Effective mass m_H of the body region in [kg] (Table A.3).
    """

    force_n: float
    transient_factor: float
    spring_n_m: float
    mass_kg: float


REGION_LIMITS: dict[str, RegionLimit] = {
    "skull_forehead": RegionLimit(130.0, 1.0, 150e3, 4.4),
    "face": RegionLimit(65.0, 1.0, 75e3, 4.4),
    "neck": RegionLimit(150.0, 1.0, 50e3, 1.2),
    "back_shoulders": RegionLimit(210.0, 2.0, 35e3, 40.0),
    "chest": RegionLimit(140.0, 2.0, 25e3, 40.0),
    "abdomen": RegionLimit(110.0, 2.0, 10e3, 40.0),
    "pelvis": RegionLimit(180.0, 2.0, 25e3, 40.0),
    "upper_arm": RegionLimit(150.0, 2.0, 30e3, 3.0),
    "lower_arm": RegionLimit(160.0, 2.0, 40e3, 2.0),
    "hand": RegionLimit(140.0, 2.0, 75e3, 0.6),
    "thigh": RegionLimit(220.0, 2.0, 50e3, 75.0),
    "lower_leg": RegionLimit(130.0, 2.0, 60e3, 75.0),
}
"""Body regions of ISO/TS 15066:2016 Annex A: maximum permissible quasi-static force (Table A.2,
body-region column), effective spring constant and effective mass (Table A.3). The transient factor
is 2 (A.3.2: transient contact values may be twice the quasi-static ones) except for the head and
the neck, kept at the quasi-static value (the standard advises against any contact with the head)."""


@dataclass(frozen=True)
class HumanPlacement:
    """Where the *assumed* human stands (recordings without a tracked skeleton).

    Attributes:
        torso_m: Position (3,) in [m] of the torso frame (``/torso_1``) in the robot base frame.
        facing_deg: Yaw in [deg] of the direction the human faces (180: toward -x, i.e. facing a
            robot whose base x axis points at the human).
    """

    torso_m: np.ndarray = field(default_factory=lambda: np.array([1.27, -0.26, 0.15]))
    facing_deg: float = 180.0


@dataclass(frozen=True)
class HumanSettings:
    """The ``[human]`` and ``[iso15066]`` tables.

    Attributes:
        radii_m: Body part name -> radius in [m] replacing the default (``ipromp_pin.human.body``).
        speed_m_s: Human speed v_h in [m/s]: S_h of S_p and the growth of unseen body parts.
        max_inflation_m: Cap in [m] of the growth of an unseen body part.
        min_separation_m: Smallest allowed distance [m] between the robot and the body outside the
            hand region (``human_clearance``).
        placement: The assumed human's placement.
        reaction_time_s: T_r, the robot system's reaction time in [s] (detection to stop command).
        stopping_time_s: T_s, the robot's stopping time in [s].
        intrusion_m: C, the intrusion distance in [m] (ISO 13855) beyond the tracked body.
        human_uncertainty_m: Z_d, the position uncertainty of the human (tracker) in [m].
        robot_uncertainty_m: Z_r, the position uncertainty of the robot in [m].
        contact: ``"transient"`` or ``"quasi_static"``: which Annex A force limits the contact
            speed is held to.
        speed_margin: Fraction in [0, 1) of the contact-speed limit that a plan keeps free: a plan
            passes ``contact_speed`` when, inside S_p, every approach is at most ``(1 - speed_margin)
            v_max``. The human keeps moving after each observation; the margin absorbs what that
            changes of distance, direction and effective mass before the next re-plan. Violations
            of what happened are still counted against ``v_max`` itself.
        regions: Body region -> its Annex A values (defaults :data:`REGION_LIMITS`, overridable).
    """

    radii_m: dict[str, float] = field(default_factory=dict)
    speed_m_s: float = ISO13855_HUMAN_SPEED_M_S
    max_inflation_m: float = 0.15
    min_separation_m: float = 0.0
    placement: HumanPlacement = field(default_factory=HumanPlacement)
    reaction_time_s: float = 0.1
    stopping_time_s: float = 0.3
    intrusion_m: float = 0.0
    human_uncertainty_m: float = 0.05
    robot_uncertainty_m: float = 0.01
    contact: str = "transient"
    speed_margin: float = 0.1
    regions: dict[str, RegionLimit] = field(default_factory=lambda: dict(REGION_LIMITS))


def _error(source: Path, name: str, problem: str) -> RobotError:
    return RobotError(f"{source}: field '{name}': {problem}")


def _number(table: dict, key: str, source: Path, prefix: str, default: float, zero_ok: bool = False) -> float:
    """``table[key]`` as a finite positive float (or >= 0 with ``zero_ok``), else ``default``."""
    if key not in table:
        return float(default)
    value = table[key]
    name = f"{prefix}.{key}"
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _error(source, name, f"must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value < 0 or (value == 0 and not zero_ok):
        raise _error(source, name, f"must be {'>= 0' if zero_ok else '> 0'} and finite, got {value}")
    return value


def _sub_table(doc: dict, key: str, source: Path, prefix: str = "") -> dict:
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise _error(source, prefix + key, "must be a table")
    return value


def _placement(table: dict, source: Path) -> HumanPlacement:
    default = HumanPlacement()
    torso = table.get("torso_m", default.torso_m.tolist())
    if not isinstance(torso, list) or len(torso) != 3:
        raise _error(source, "human.assumed.torso_m", "must be a list of 3 numbers")
    try:
        arr = np.asarray(torso, dtype=float)
    except (TypeError, ValueError):
        raise _error(source, "human.assumed.torso_m", "must contain numbers only") from None
    if not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > 10.0):
        raise _error(source, "human.assumed.torso_m", f"must be finite and within 10 m, got {arr.tolist()}")
    facing = table.get("facing_deg", default.facing_deg)
    if isinstance(facing, bool) or not isinstance(facing, int | float) or not math.isfinite(facing):
        raise _error(source, "human.assumed.facing_deg", f"must be a finite number, got {facing!r}")
    return HumanPlacement(arr, float(facing))


def _regions(table: dict, source: Path) -> dict[str, RegionLimit]:
    out = dict(REGION_LIMITS)
    for region, values in table.items():
        prefix = f"iso15066.regions.{region}"
        if region not in out:
            raise _error(source, prefix, f"unknown body region (known: {', '.join(REGION_LIMITS)})")
        if not isinstance(values, dict):
            raise _error(source, prefix, "must be a table")
        d = out[region]
        out[region] = RegionLimit(
            _number(values, "force_n", source, prefix, d.force_n),
            _number(values, "transient_factor", source, prefix, d.transient_factor),
            _number(values, "spring_n_mm", source, prefix, d.spring_n_m / 1e3) * 1e3,
            _number(values, "mass_kg", source, prefix, d.mass_kg),
        )
    return out


def _margin(iso: dict, source: Path, default: float) -> float:
    value = iso.get("speed_margin", default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= float(value) < 1.0:
        raise _error(source, "iso15066.speed_margin", f"must be a number in [0, 1), got {value!r}")
    return float(value)


def read_human_settings(doc: dict, source: Path) -> HumanSettings:
    """The validated ``[human]`` / ``[iso15066]`` tables of a settings document (defaults when absent).

    Raises:
        RobotError: a non-positive or non-finite value, an unknown body region or contact kind,
            naming the file and the field.
    """
    human = _sub_table(doc, "human", source)
    iso = _sub_table(doc, "iso15066", source)
    d = HumanSettings()
    radii_raw = human.get("radii_m", {})
    if not isinstance(radii_raw, dict):
        raise _error(source, "human.radii_m", "must be a table (body part = radius in m)")
    radii = {k: _number(radii_raw, k, source, "human.radii_m", 0.0) for k in radii_raw}
    for k, r in radii.items():
        if r > 1.0:
            raise _error(source, f"human.radii_m.{k}", f"implausible radius {r} m (at most 1 m)")
    contact = iso.get("contact", d.contact)
    if contact not in ("transient", "quasi_static"):
        raise _error(source, "iso15066.contact", f"must be 'transient' or 'quasi_static', got {contact!r}")
    return HumanSettings(
        radii_m=radii,
        speed_m_s=_number(human, "speed_m_s", source, "human", d.speed_m_s),
        max_inflation_m=_number(human, "max_inflation_m", source, "human", d.max_inflation_m, True),
        min_separation_m=_number(human, "min_separation_m", source, "human", d.min_separation_m, True),
        placement=_placement(_sub_table(human, "assumed", source, "human."), source),
        reaction_time_s=_number(iso, "reaction_time_s", source, "iso15066", d.reaction_time_s, True),
        stopping_time_s=_number(iso, "stopping_time_s", source, "iso15066", d.stopping_time_s, True),
        intrusion_m=_number(iso, "intrusion_m", source, "iso15066", d.intrusion_m, True),
        human_uncertainty_m=_number(
            iso, "human_uncertainty_m", source, "iso15066", d.human_uncertainty_m, True
        ),
        robot_uncertainty_m=_number(
            iso, "robot_uncertainty_m", source, "iso15066", d.robot_uncertainty_m, True
        ),
        contact=str(contact),
        speed_margin=_margin(iso, source, d.speed_margin),
        regions=_regions(_sub_table(iso, "regions", source, "iso15066."), source),
    )
