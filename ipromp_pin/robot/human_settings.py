"""The human side of a robot settings file: the ``[human]`` and ``[iso15066]`` tables, validated.

``[human]`` holds the body model's parameters (radii overrides per body part, the speed at which an
unseen body part may move, the cap of that inflation) and the placement of the *assumed* human used
when a recording has no tracked skeleton, and the skeleton map (which frames of a recording are the
body's joints, :mod:`.skeleton_maps`); ``[iso15066]`` holds the parameters of the protective
separation distance (ISO/TS 15066:2016 clause 5.5.4) and overrides of the Annex A body-region limits.
The ISO/TS's content is now part of ISO 10218-2:2025 and ISO 13855:2024 replaced the 2010 edition;
the clauses cited are those of the documents the values were read from (``docs/safety.md``, *The
standards and their editions*: no value changed as far as the new editions' published changes say).
Every key is known or refused (with the known one it resembles), every value lies in its plausible
range (:mod:`ipromp_pin.robot.ranges`, whose source the message names); the defaults and their
sources are described in ``docs/safety.md`` and in the shipped ``robots/*.toml``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fields import Table
from .ranges import BODY_PART_RADII_M, PLAUSIBLE_RANGES, radius_range, region_range
from .skeleton_maps import MAP_KEYS, SKELETONS, SkeletonMap

ISO13855_HUMAN_SPEED_M_S = 1.6
"""Walking speed of a person approaching a machine, ISO 13855:2010 clause 6.2.3 (K = 1600 mm/s for
distances over 500 mm; ISO 13855:2024, which replaced it, lists no change of the approach speeds in its
published changes, not verified against its text): the human speed of S_h unless measured."""


@dataclass(frozen=True)
class RegionLimit:
    """ISO/TS 15066:2016 Annex A values of one body region (the ISO/TS's content is now in
    ISO 10218-2:2025; table numbers are the ISO/TS's).

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
"""Body regions of ISO/TS 15066:2016 Annex A (now in ISO 10218-2:2025; no changed value found in
what is published about it, not verified against its text): maximum permissible quasi-static force (Table A.2,
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
        speed_margin: Fraction in [0, 0.5] of the contact-speed limit that a plan keeps free: a plan
            passes ``contact_speed`` when, inside S_p, every approach is at most ``(1 - speed_margin)
            v_max``. The human keeps moving after each observation; the margin absorbs what that
            changes of distance, direction and effective mass before the next re-plan. Violations
            of what happened are still counted against ``v_max`` itself.
        regions: Body region -> its Annex A values (defaults :data:`REGION_LIMITS`, overridable).
        skeleton: Which frames of a recording's tracked skeleton are the body's joints
            (:mod:`ipromp_pin.robot.skeleton_maps`; default the OpenNI frames).
        handing_arm: ``"predicted"``: after the last observation the handing arm is placed where the
            model predicts it, where its cross-validated error is a tighter bound than holding it
            (:mod:`ipromp_pin.planning.human_forecast`); ``"held"``: every frame is held where last seen.
        source: The settings file the values come from (for messages; ``""``: built in code).
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
    skeleton: SkeletonMap = field(default_factory=lambda: SKELETONS["openni"])
    handing_arm: str = "predicted"
    source: str = ""


HANDING_ARMS = ("predicted", "held")
"""Values of ``[human] handing_arm``."""

HUMAN_KEYS = (
    "speed_m_s",
    "max_inflation_m",
    "min_separation_m",
    "radii_m",
    "assumed",
    "skeleton",
    "skeleton_map",
    "handing_arm",
)
"""Keys of the ``[human]`` table."""

ASSUMED_KEYS = ("torso_m", "facing_deg")
"""Keys of the ``[human.assumed]`` table."""

ISO15066_KEYS = (
    "reaction_time_s",
    "stopping_time_s",
    "intrusion_m",
    "human_uncertainty_m",
    "robot_uncertainty_m",
    "contact",
    "speed_margin",
    "regions",
)
"""Keys of the ``[iso15066]`` table."""

REGION_KEYS = ("force_n", "transient_factor", "spring_n_mm", "mass_kg")
"""Keys of an ``[iso15066.regions.<region>]`` table."""

CONTACTS = ("transient", "quasi_static")
"""Values of ``[iso15066] contact``."""


def _ranged(table: Table, key: str, default: float) -> float:
    return table.number(key, PLAUSIBLE_RANGES[table.field(key)], default)


def _placement(human: Table) -> HumanPlacement:
    table = human.table("assumed", ASSUMED_KEYS)
    d = HumanPlacement()
    torso = table.vector("torso_m", 3, PLAUSIBLE_RANGES["human.assumed.torso_m"], d.torso_m)
    return HumanPlacement(torso, _ranged(table, "facing_deg", d.facing_deg))


def _regions(iso: Table) -> dict[str, RegionLimit]:
    out = dict(REGION_LIMITS)
    regions = iso.table("regions", REGION_LIMITS, what="body region")
    for region in regions.keys():
        table = regions.table(region, REGION_KEYS, required=True)
        d = out[region]
        out[region] = RegionLimit(
            table.number("force_n", region_range(region, "force_n", d.force_n), d.force_n),
            table.number(
                "transient_factor",
                region_range(region, "transient_factor", d.transient_factor),
                d.transient_factor,
            ),
            table.number(
                "spring_n_mm", region_range(region, "spring_n_mm", d.spring_n_m / 1e3), d.spring_n_m / 1e3
            )
            * 1e3,
            table.number("mass_kg", region_range(region, "mass_kg", d.mass_kg), d.mass_kg),
        )
    return out


def _radii(human: Table) -> dict[str, float]:
    table = human.table("radii_m", BODY_PART_RADII_M, what="body part")
    return {part: table.number(part, radius_range(part)) for part in table.keys()}


def _frame_names(table: Table, joint: str) -> tuple[str, ...]:
    """A ``[human.skeleton_map]`` joint: one frame name, or a non-empty list of them (their mean)."""
    value = table.raw(joint)
    names = [value] if isinstance(value, str) else value
    if not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names):
        raise table.error(joint, f"must be a frame name or a non-empty list of frame names, got {value!r}")
    if len(set(names)) != len(names):
        raise table.error(joint, f"lists a frame twice: {names!r}")
    return tuple(names)


def _skeleton(human: Table) -> SkeletonMap:
    """``[human] skeleton`` (a shipped map's name) with the joints ``[human.skeleton_map]`` replaces."""
    base = SKELETONS[human.text("skeleton", "openni", SKELETONS)]
    table = human.table("skeleton_map", MAP_KEYS, what="skeleton map key")
    if not table.keys():
        return base
    frames = dict(base.frames)
    frames.update({j: _frame_names(table, j) for j in table.keys() if j != "mirrored"})
    mirrored = table.raw("mirrored", base.mirrored)
    if not isinstance(mirrored, bool):
        raise table.error("mirrored", f"must be true or false, got {mirrored!r}")
    return SkeletonMap(f"{base.name}+[human.skeleton_map]", frames, mirrored)


def read_human_settings(doc: Table, source: object) -> HumanSettings:
    """The validated ``[human]`` / ``[iso15066]`` tables of the settings document ``doc`` of file
    ``source`` (defaults when absent).

    Raises:
        RobotError: an unknown key, table, body part or region (with the known name it resembles), a
            value that is not a finite number or lies outside its plausible range
            (:data:`~ipromp_pin.robot.ranges.PLAUSIBLE_RANGES`, whose source the message names), an
            unknown contact kind or shipped skeleton map, a skeleton map's frame that is not a name;
            naming the file and the field.
    """
    human = doc.table("human", HUMAN_KEYS)
    iso = doc.table("iso15066", ISO15066_KEYS)
    d = HumanSettings()
    return HumanSettings(
        radii_m=_radii(human),
        speed_m_s=_ranged(human, "speed_m_s", d.speed_m_s),
        max_inflation_m=_ranged(human, "max_inflation_m", d.max_inflation_m),
        min_separation_m=_ranged(human, "min_separation_m", d.min_separation_m),
        placement=_placement(human),
        reaction_time_s=_ranged(iso, "reaction_time_s", d.reaction_time_s),
        stopping_time_s=_ranged(iso, "stopping_time_s", d.stopping_time_s),
        intrusion_m=_ranged(iso, "intrusion_m", d.intrusion_m),
        human_uncertainty_m=_ranged(iso, "human_uncertainty_m", d.human_uncertainty_m),
        robot_uncertainty_m=_ranged(iso, "robot_uncertainty_m", d.robot_uncertainty_m),
        contact=iso.text("contact", d.contact, CONTACTS),
        speed_margin=_ranged(iso, "speed_margin", d.speed_margin),
        regions=_regions(iso),
        skeleton=_skeleton(human),
        handing_arm=human.text("handing_arm", d.handing_arm, HANDING_ARMS),
        source=str(source),
    )
