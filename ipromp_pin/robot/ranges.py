"""Plausible ranges of the safety values, with their sources: one table (:data:`PLAUSIBLE_RANGES`).

Keys are the dotted fields of the settings files: robot settings (``limits.*``, ``checks.*``,
``human.*``, ``iso15066.*``; ``<region>`` stands for every ISO/TS 15066 body region, ``<part>`` for
every body part, ``<joint>`` for a joint), objects files (``<task>.*``), limit-profile files (their
keys are the robot settings' ``limits.*``), and ``skeleton.<part>``: the segment lengths of a tracked
skeleton (:mod:`ipromp_pin.human.skeleton`). A value outside its range is refused, naming the range
and its source (:class:`~ipromp_pin.fields.Range`); nothing is clamped. Rows whose bounds depend on
the region or part (:func:`region_range`, :func:`radius_range`) give the widest bounds and say how
each is narrowed. ``docs/safety.md`` lists the same table (a test compares them).
"""

from __future__ import annotations

from ..fields import Range

BODY_PART_RADII_M: dict[str, float] = {
    "head": 0.11,
    "neck": 0.07,
    "shoulders": 0.08,
    "chest": 0.17,
    "abdomen": 0.16,
    "pelvis": 0.14,
    "left_upper_arm": 0.065,
    "right_upper_arm": 0.065,
    "left_forearm": 0.055,
    "right_forearm": 0.055,
    "left_hand": 0.10,
    "right_hand": 0.10,
    "left_thigh": 0.10,
    "right_thigh": 0.10,
}
"""Default radius [m] of every body part of the body model (:data:`ipromp_pin.human.BODY_PARTS`):
half of a 95th-percentile adult male body dimension, rounded up (docs/safety.md, "The body")."""

RADIUS_FACTORS = (0.5, 2.0)
"""A ``[human] radii_m`` override lies between these multiples of the part's default radius."""

SEGMENT_FRACTIONS: dict[str, float] = {
    "neck": 0.117,
    "shoulders": 0.259,
    "chest": 0.144,
    "abdomen": 0.144,
    "pelvis": 0.191,
    "left_upper_arm": 0.186,
    "right_upper_arm": 0.186,
    "left_forearm": 0.146,
    "right_forearm": 0.146,
    "left_thigh": 0.245,
    "right_thigh": 0.245,
}
"""Length of each capsule part between two tracked frames as a fraction of stature H: upper arm
0.186, forearm (elbow to wrist) 0.146, thigh 0.245, shoulder width 0.259, hip width 0.191; neck to
head centre 0.117 (shoulder height 0.818 to the middle of chin 0.870 and crown 1.0) and the two
trunk halves 0.144 each (shoulder height 0.818 to hip height 0.530) (Drillis and Contini 1966, as
drawn in Winter, "Biomechanics and Motor Control of Human Movement", Fig. 4.1)."""

STATURE_M = (1.4, 2.1)
"""Adult statures [m] the skeleton may have: wider than ANSUR II's 5th-percentile woman (1.52 m) and
95th-percentile man (1.87 m)."""

TRACKER_FACTORS = (0.5, 1.5)
"""The tracker's frames are joint-centre estimates, not anatomical landmarks: a segment may measure
between these multiples of its anatomical length (the OpenNI skeleton of handover_20171128 measures
its median segments at 0.48 (hips) to 0.90 (forearm, neck) of a 1.75 m adult's: docs/safety.md)."""

_SKELETON_SOURCE = (
    "segment / stature {f:g} (Drillis and Contini 1966, Winter Fig. 4.1) for statures 1.4-2.1 m, "
    "x 0.5-1.5 for the tracker's joint centres"
)


def _segment(fraction: float, longest: float | None = None) -> Range:
    lo = round(fraction * STATURE_M[0] * TRACKER_FACTORS[0], 3)
    hi = round((longest or fraction) * STATURE_M[1] * TRACKER_FACTORS[1], 3)
    return Range(lo, hi, "m", _SKELETON_SOURCE.format(f=fraction))


_REGION_SOURCE_A2 = (
    "ISO/TS 15066:2016 Table A.2 (its content now in ISO 10218-2:2025): at most the region's own "
    "maximum permissible quasi-static force (more is outside the standard), at least the strictest "
    "any region has (face, 65 N)"
)

PLAUSIBLE_RANGES: dict[str, Range] = {
    # --- robot settings: [limits], [checks], [calibration], [workspace], [fixed_joints], [springs]
    "limits.position_margin_rad": Range(
        0.0, 0.5, "rad",
        "the recorded demonstrations come within 0.009 rad of Baxter's limits; 0.5 rad is a fifth of "
        "a joint's range (Baxter e1: 2.67 rad)",
    ),
    "limits.velocity_rad_s": Range(
        1e-3, 100.0, "rad/s",
        "real arms' URDF limits: Baxter 1.5-4 rad/s, Panda 2.2-2.6 rad/s; below, a motion takes hours",
    ),
    "limits.acceleration_rad_s2": Range(
        1e-3, 1e4, "rad/s^2",
        "Baxter 1 rad/s^2 (Rethink's MoveIt configuration), Panda 7.5-20 rad/s^2 (Franka's datasheet)",
    ),
    "limits.jerk_rad_s3": Range(
        1e-2, 1e6, "rad/s^3",
        "Baxter 10 rad/s^3 (robots/baxter_left.toml), Panda's hardware 500 times its accelerations "
        "(libfranka)",
    ),
    "limits.effort_margin": Range(
        0.0, 0.5, "",
        "0.1: room for the URDF's link inertias, not identified on the robot; above 0.5 the check "
        "withholds half the torque, no longer a margin",
    ),
    "limits.demonstrated.percentile": Range(0.0, 100.0, "", "a percentile", lo_open=True),
    "limits.demonstrated.window_s": Range(
        0.0, 5.0, "s",
        "a Savitzky-Golay window (0.34 s, docs/closed_loop.md): a longer one smooths away the 1.5-5 s "
        "hand-overs",
        lo_open=True,
    ),
    "checks.min_clearance_m": Range(
        0.0, 1.0, "m",
        "a self-collision clearance of 1 m exceeds the distance between an arm's own links: every "
        "path would fail",
    ),
    "checks.collision_max_step_rad": Range(
        1e-3, 1.0, "rad",
        "below 1e-3 rad a path needs 1000 collision checks per radian; above 1 rad links pass through "
        "each other between two checks",
    ),
    "calibration.tool_offset_m": Range(
        -1.0, 1.0, "m", "calibration corrects millimetres (Baxter's mount: 10 mm); per axis"
    ),
    "calibration.mount_offset_m": Range(
        -1.0, 1.0, "m", "calibration corrects millimetres (Baxter's mount: 10 mm); per axis"
    ),
    "placement.xyz_m": Range(
        -3.0, 3.0, "m",
        "a target arm mounted within 3 m of the source robot's base: the recorded hand-overs lie within "
        "1.2 m of it and the arms reach at most 1 m; per axis",
    ),
    "placement.rpy_deg": Range(-180.0, 180.0, "deg", "roll, pitch, yaw angles, each at most half a turn"),
    "end_effector.rpy_deg": Range(-180.0, 180.0, "deg", "roll, pitch, yaw angles, each at most half a turn"),
    "tool.length_m": Range(
        0.01, 0.4, "m",
        "flange to tool centre point of a hand-over gripper: the xArm Gripper's is 0.172 m (xarm_ros2), a "
        "Robotiq 2F-85's 0.15 m plus its 8 mm coupling; beyond 0.4 m the tool is an arm link of its own",
    ),
    "tool.radius_m": Range(
        0.01, 0.2, "m",
        "half the width of a gripper with its fingers open: 85-86 mm strokes plus the fingers make "
        "0.1-0.15 m across",
    ),
    "tool.mass_kg": Range(
        0.0, 5.0, "kg",
        "a hand-over gripper weighs 0.5-1.5 kg (xArm Gripper about 0.75 kg, xarm_ros2's links; Robotiq "
        "2F-85 0.925 kg); the arms here carry 3-5 kg in all",
    ),
    "workspace.min_m": Range(-10.0, 10.0, "m", "within the readers' tracking range (10 m from the base)"),
    "workspace.max_m": Range(-10.0, 10.0, "m", "within the readers' tracking range (10 m from the base)"),
    "workspace.center_m": Range(-10.0, 10.0, "m", "within the readers' tracking range (10 m from the base)"),
    "workspace.radius_m": Range(
        0.0, 10.0, "m", "within the readers' tracking range (10 m from the base)", lo_open=True
    ),
    "fixed_joints.<joint>": Range(
        -10.0, 10.0, "rad or m",
        "one and a half turns; each joint's own URDF limits are checked when the model is built",
    ),
    "springs.<joint>": Range(
        -1000.0, 1000.0, "N m, N m/rad",
        "Baxter's s1 counterbalance is -40.3 N m - 24.5 N m/rad q (benchmarks/baxter_springs.py); 1000 "
        "is 20 times its 50 N m effort limit",
    ),
    # --- robot settings: [human], [human.assumed]
    "human.speed_m_s": Range(
        1.6, 2.0, "m/s",
        "ISO 13855 approach speeds K (2010 clause 6.2.3: 1600 mm/s walking, 2000 mm/s hand and arm; "
        "ISO 13855:2024's values not verified against its text), v_h of the protective separation "
        "distance (ISO/TS 15066:2016 clause 5.5.4, now in ISO 10218-2:2025)",
    ),
    "human.max_inflation_m": Range(
        0.07, 1.0, "m",
        "at least the 0.07 m the head, trunk and other arm move within a demo of handover_20171128 "
        "(90th percentile, docs/safety.md); at most 1 m, an arm's length",
    ),
    "human.min_separation_m": Range(
        0.0, 0.5, "m",
        "the gripper must come within the human's reach (shoulder to hand about 0.6 m): a gap above "
        "0.5 m leaves no hand-over",
    ),
    "human.radii_m.<part>": Range(
        RADIUS_FACTORS[0] * min(BODY_PART_RADII_M.values()),
        RADIUS_FACTORS[1] * max(BODY_PART_RADII_M.values()),
        "m",
        "half to twice the part's default radius, itself about the 95th-percentile adult male "
        "(ANSUR II, DIN 33402-2: docs/safety.md)",
    ),
    "human.assumed.torso_m": Range(
        -10.0, 10.0, "m", "within the readers' tracking range (10 m from the base); per axis"
    ),
    "human.assumed.facing_deg": Range(-360.0, 360.0, "deg", "a yaw within one turn either way"),
    # --- robot settings: [iso15066]
    "iso15066.reaction_time_s": Range(
        0.01, 2.0, "s",
        "T_r: at least one cycle of a 100 Hz control loop (a 30 Hz skeleton tracker alone adds 33 ms); "
        "in 2 s a walking human covers 3.2 m",
    ),
    "iso15066.stopping_time_s": Range(
        0.05, 5.0, "s",
        "T_s (ISO 10218-1:2011 asks the manufacturer for the measured value): stopping from 1 m/s in "
        "0.05 s decelerates at 2 g; engineering bounds",
    ),
    "iso15066.intrusion_m": Range(
        0.0, 1.2, "m",
        "C of ISO 13855:2010: 850 mm for an arm reaching through a detection zone, up to 1200 mm "
        "reaching over one (ISO 13855:2024 splits it into D_DS and Z; not verified against its text)",
    ),
    "iso15066.human_uncertainty_m": Range(
        0.0, 0.5, "m",
        "Z_d: a skeleton tracker errs by centimetres (0.05 m assumed for a depth camera); off by "
        "0.5 m it tracks no body",
    ),
    "iso15066.robot_uncertainty_m": Range(
        0.0, 0.1, "m",
        "Z_r: Baxter's FK residual is 1.1 mm after calibration, 10.6 mm before (robots/baxter_left.toml)",
    ),
    "iso15066.speed_margin": Range(
        0.0, 0.5, "",
        "0.1 chosen by cross-validation on training demos (benchmarks/speed_margin_cv.py, "
        "docs/safety.md); above 0.5 a plan is slowed twice for the margin alone",
    ),
    "iso15066.regions.<region>.force_n": Range(65.0, 220.0, "N", _REGION_SOURCE_A2),
    "iso15066.regions.<region>.transient_factor": Range(
        1.0, 2.0, "",
        "ISO/TS 15066:2016 Annex A.3.2: transient contact up to twice the quasi-static values; at "
        "most the region's default (1 for the head and neck)",
    ),
    "iso15066.regions.<region>.spring_n_mm": Range(
        10.0, 150.0, "N/mm",
        "ISO/TS 15066:2016 Table A.3: at least the region's own effective spring constant (a softer "
        "one raises its speed limit), at most the stiffest any region has (skull, 150 N/mm)",
    ),
    "iso15066.regions.<region>.mass_kg": Range(
        0.6, 75.0, "kg",
        "ISO/TS 15066:2016 Table A.3: at least the region's own effective mass (a lighter one raises "
        "its speed limit), at most the heaviest any region has (75 kg, the legs)",
    ),
    # --- objects files
    "<task>.mass_kg": Range(
        0.0, 35.0, "kg",
        "at most the largest rated payload of a collaborative arm (35 kg, FANUC CR-35iA); Baxter's is "
        "2.2 kg and the joint-torque check refuses what its arm cannot hold",
    ),
    "<task>.com_m": Range(0.0, 1.0, "m", "distance from the gripper frame: an object held by the gripper"),
    "<task>.shape.size_m": Range(1e-3, 2.0, "m", "a hand-held object, 1 mm to 2 m"),
    "<task>.shape.radius_m": Range(1e-3, 1.0, "m", "a hand-held object, 1 mm to 2 m across"),
    "<task>.shape.length_m": Range(1e-3, 2.0, "m", "a hand-held object, 1 mm to 2 m"),
    "<task>.inertia_kg_m2": Range(
        0.0, 1.0, "m",
        "radius of gyration sqrt(I / m) of each principal moment: at most 1 m, as for an object at "
        "most 2 m long",
    ),
    "<task>.retreat.dwell_s": Range(
        0.0, 10.0, "s", "the arm holds still at the hand-over while the gripper closes or opens"
    ),
    "<task>.retreat.position_m": Range(
        0.0, 2.0, "m", "distance from the base frame's origin: Baxter reaches about 1.2 m"
    ),
    # --- tracked skeletons (not a settings file: the recordings' segment lengths)
    "skeleton.neck": _segment(SEGMENT_FRACTIONS["neck"]),
    "skeleton.shoulders": _segment(SEGMENT_FRACTIONS["shoulders"]),
    "skeleton.chest": _segment(SEGMENT_FRACTIONS["chest"]),
    "skeleton.abdomen": _segment(SEGMENT_FRACTIONS["abdomen"]),
    "skeleton.pelvis": _segment(SEGMENT_FRACTIONS["pelvis"]),
    "skeleton.upper_arm": _segment(SEGMENT_FRACTIONS["left_upper_arm"]),
    "skeleton.forearm": Range(
        _segment(0.146).lo, _segment(0.146, 0.146 + 0.108).hi, "m",
        "segment / stature 0.146 to the wrist, 0.254 with the hand (Drillis and Contini 1966, Winter "
        "Fig. 4.1) for statures 1.4-2.1 m, x 0.5-1.5 for the tracker's joint centres",
    ),
    "skeleton.thigh": _segment(SEGMENT_FRACTIONS["left_thigh"]),
}  # fmt: skip
"""Field -> its plausible range and source (see the module docstring)."""


def region_range(region: str, key: str, default: float) -> Range:
    """The range of ``[iso15066.regions.<region>] key``, narrowed to the region's own Annex A value
    ``default`` (in the key's unit): the standard's side bounded by it, the strict side by the row."""
    row = PLAUSIBLE_RANGES[f"iso15066.regions.<region>.{key}"]
    if key in ("force_n", "transient_factor"):  # larger is less safe
        return row.narrowed(lo=min(row.lo, default), hi=default)
    return row.narrowed(lo=default, hi=max(row.hi, default))  # spring constant, mass: smaller is less safe


def radius_range(part: str) -> Range:
    """The range of ``[human] radii_m.<part>``: :data:`RADIUS_FACTORS` times the part's default."""
    r = BODY_PART_RADII_M[part]
    return PLAUSIBLE_RANGES["human.radii_m.<part>"].narrowed(RADIUS_FACTORS[0] * r, RADIUS_FACTORS[1] * r)


def segment_range(part: str) -> Range:
    """The range of the length of body part ``part`` between its two tracked frames."""
    name = part.removeprefix("left_").removeprefix("right_")
    return PLAUSIBLE_RANGES[f"skeleton.{name}"]
