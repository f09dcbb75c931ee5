"""The objects of the tasks: what the gripper holds, and when (task files, ``robots/objects.toml``).

A task file is TOML with one table per task (the task names of the recordings, e.g.
``[spanner_handover]``)::

    schema_version = 1
    [spanner_handover]
    mass_kg = 0.25                 # [kg], finite, >= 0
    com_m = [0.0, 0.0, 0.06]       # centre of mass in the gripper frame [m], at most 1 m from it
    holder = "robot_gives"         # the robot carries it until the hand-over ("robot_receives": from it on)
    shape = { kind = "box", size_m = [0.02, 0.04, 0.2] }   # or kind = "cylinder", radius_m, length_m, axis
    # or: inertia_kg_m2 = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]] about the centre of mass
    source = "why these numbers"   # optional, shown in reports
    retreat = { to = "start" }     # optional: where the arm goes after the hand-over (retreat_target)

:func:`load_objects` reads and validates one (a :class:`~ipromp_pin.exceptions.RobotError` naming the
file, the field and the problem, before anything is computed); :meth:`ObjectTable.check_tasks` refuses
task names the data does not have, :meth:`ObjectTable.check_robot` retreat targets the robot cannot
take (:mod:`ipromp_pin.robot.retreat_target`). :mod:`ipromp_pin.robot.dynamics` attaches an object to
the gripper frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import RobotError
from ..fields import REQUIRED, FieldError, Range, Table, did_you_mean, field_errors, numbers
from ..inputs import load_toml
from ..shipped import ROBOTS_DIR
from .model import Robot
from .ranges import PLAUSIBLE_RANGES
from .retreat_target import RetreatTarget, check_retreat_robot, parse_retreat
from .settings import settings_error

DEFAULT_OBJECTS = ROBOTS_DIR / "objects.toml"
"""The shipped task file (assumed objects of the shared recordings' tasks and the synthetic ones)."""

HOLDERS = ("robot_gives", "robot_receives")
"""``robot_gives``: the robot holds the object until the hand-over; ``robot_receives``: from it on."""

MAX_COM_DISTANCE_M = PLAUSIBLE_RANGES["<task>.com_m"].hi
"""Largest distance of an object's centre of mass from the gripper frame's origin [m]."""

_KEYS = ("mass_kg", "com_m", "holder", "shape", "inertia_kg_m2", "source", "retreat")


@dataclass(frozen=True)
class TaskObject:
    """The object of one task.

    Attributes:
        task: Task name.
        mass_kg: Mass in [kg].
        com_m: Centre of mass (3,) in [m], in the gripper frame.
        inertia_kg_m2: Rotational inertia (3, 3) in [kg m^2] about the centre of mass, gripper axes (PSD).
        holder: ``"robot_gives"`` or ``"robot_receives"`` (:data:`HOLDERS`).
        source: Where the numbers come from (free text).
        retreat: Where the arm goes after the hand-over (``None``: it stays there).
        shape: The task file's ``shape`` table (``kind`` "box" with ``size_m``, or "cylinder" with
            ``radius_m``, ``length_m``, ``axis``), centred at ``com_m`` in the gripper axes; ``None``
            when the file gives none (the previews then draw a small sphere at ``com_m``).
    """

    task: str
    mass_kg: float
    com_m: np.ndarray
    inertia_kg_m2: np.ndarray
    holder: str
    source: str = ""
    retreat: RetreatTarget | None = None
    shape: dict[str, Any] | None = None

    def held_at(self, t_s: np.ndarray, handover_s: float | None) -> np.ndarray:
        """Whether the robot holds the object at times ``t_s`` (N,) [s] on the human's clock, given the
        hand-over time ``handover_s`` [s] (unknown: the whole motion, the conservative choice)."""
        t = np.asarray(t_s, dtype=float)
        if handover_s is None:
            return np.ones(t.shape, dtype=bool)
        if self.holder == "robot_gives":
            return t <= handover_s + 1e-9
        return t >= handover_s - 1e-9

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (reports)."""
        return {
            "task": self.task,
            "mass_kg": self.mass_kg,
            "com_m": [float(x) for x in self.com_m],
            "holder": self.holder,
            "source": self.source,
        }


@dataclass(frozen=True)
class ObjectTable:
    """A validated task file: task name -> :class:`TaskObject`.

    Attributes:
        path: The file read (for messages).
        objects: Task name -> object.
    """

    path: Path
    objects: dict[str, TaskObject] = field(default_factory=dict)

    def for_task(self, task: str | None) -> TaskObject | None:
        """The object of ``task`` (``None``: the task has no entry, no payload)."""
        return None if task is None else self.objects.get(task)

    def check_tasks(self, known: list[str] | tuple[str, ...]) -> None:
        """Refuse a task name that is not one of ``known`` (the data's tasks).

        Raises:
            RobotError: naming the file, the table and the known tasks.
        """
        for task in self.objects:
            if task not in known:
                raise settings_error(
                    self.path, task, f"unknown task '{task}' (the data's tasks: {', '.join(known)})"
                )

    def check_robot(self, robot: Robot) -> None:
        """Refuse a retreat target that does not fit ``robot`` (:func:`check_retreat_robot`).

        Raises:
            RobotError: naming the file, the field and the problem.
        """
        for obj in self.objects.values():
            if obj.retreat is not None:
                check_retreat_robot(obj.retreat, robot)


def box_inertia(mass_kg: float, size_m: np.ndarray) -> np.ndarray:
    """Inertia (3, 3) [kg m^2] of a solid box of edge lengths ``size_m`` (3,) [m] about its centre."""
    x, y, z = (float(v) ** 2 for v in size_m)
    return mass_kg / 12.0 * np.diag([y + z, x + z, x + y])


def cylinder_inertia(mass_kg: float, radius_m: float, length_m: float, axis: int) -> np.ndarray:
    """Inertia (3, 3) [kg m^2] of a solid cylinder about its centre, its axis along ``axis`` (0-2)."""
    perp = mass_kg * (3.0 * radius_m**2 + length_m**2) / 12.0
    diag = np.full(3, perp)
    diag[axis] = 0.5 * mass_kg * radius_m**2
    return np.diag(diag)


SHAPE_KEYS = {"box": ("kind", "size_m"), "cylinder": ("kind", "radius_m", "length_m", "axis")}
"""The keys of a ``shape`` table, per kind."""

INERTIA_SYMMETRY_RTOL = 1e-9
"""An ``inertia_kg_m2`` is symmetric when ``|I - I^T| <= 1e-9 max|I|`` entry by entry: the round-off
of a matrix computed by a program (1e-16 relative) or printed with 10 significant digits or more
passes, an entry typed differently on either side of the diagonal does not. It is then replaced by
``(I + I^T) / 2``, exactly symmetric, which Pinocchio requires (it refuses a 1e-13 asymmetry)."""


def _range(key: str) -> Range:
    """The plausible range of a task's ``key`` (``"<task>.key"`` in :data:`PLAUSIBLE_RANGES`)."""
    return PLAUSIBLE_RANGES[f"<task>.{key}"]


def _shape_inertia(table: Table, mass: float) -> np.ndarray:
    shape = table.table("shape", ("kind", "size_m", "radius_m", "length_m", "axis"))
    kind = shape.text("kind", REQUIRED, SHAPE_KEYS)
    shape = Table(shape.data, shape.prefix, shape.error_fn, SHAPE_KEYS[kind])
    if kind == "box":
        size = shape.vector("size_m", 3, _range("shape.size_m"))
        return box_inertia(mass, size)
    radius = shape.number("radius_m", _range("shape.radius_m"))
    length = shape.number("length_m", _range("shape.length_m"))
    axis = shape.text("axis", "z", ("x", "y", "z"))
    return cylinder_inertia(mass, radius, length, "xyz".index(axis))


def _inertia_matrix(table: Table, mass: float) -> np.ndarray:
    """``inertia_kg_m2``: symmetric to :data:`INERTIA_SYMMETRY_RTOL` (then symmetrised exactly),
    positive definite (zero for a massless object), principal moments obeying the triangle
    inequality and a radius of gyration in its plausible range."""
    key = "inertia_kg_m2"
    value = table.raw(key)
    if not (isinstance(value, list) and len(value) == 3):
        raise table.error(key, "must be a 3 x 3 list of lists [kg m^2]")
    inertia = np.stack([numbers(row, 3, table.field(key), table.error_fn) for row in value])
    scale = float(np.max(np.abs(inertia)))
    asym = float(np.max(np.abs(inertia - inertia.T)))
    if asym > INERTIA_SYMMETRY_RTOL * scale:
        raise table.error(
            key, f"must be symmetric (|I - I^T| up to {asym:.3g}, above {INERTIA_SYMMETRY_RTOL:g} x max |I|)"
        )
    inertia = (inertia + inertia.T) / 2.0
    if mass == 0:
        if scale > 0:
            raise table.error(
                key, "a massless object (mass_kg = 0) has no inertia: give zeros or leave it out"
            )
        return inertia
    eig = np.linalg.eigvalsh(inertia)
    if eig[0] <= 0:
        raise table.error(key, f"must be positive definite (eigenvalues {eig.round(9).tolist()})")
    if eig[2] > eig[0] + eig[1] + 1e-12 * eig[2]:
        raise table.error(
            key,
            f"principal moments {eig.round(9).tolist()} violate the triangle inequality "
            "(each at most the sum of the other two: no rigid body has them)",
        )
    gyration = float(np.sqrt(eig[2] / mass))
    rng = _range(key)
    if not rng.contains(gyration):
        raise table.error(key, f"radius of gyration {rng.problem(gyration)}")
    return inertia


def _task_object(task: str, value: object, path: Path, error: FieldError) -> TaskObject:
    if not isinstance(value, dict):
        hint = did_you_mean(task, ["schema_version"])  # the only top-level value
        problem = "must be a table (mass_kg, com_m, holder, shape or inertia_kg_m2)"
        raise error(task, f"unknown key{hint}" if hint else problem)
    table = Table(value, task, error, _KEYS)
    mass = table.number("mass_kg", _range("mass_kg"))
    com = table.vector("com_m", 3, None, [0.0, 0.0, 0.0])
    _range("com_m").check(float(np.linalg.norm(com)), table.field("com_m"), error)
    holder = table.text("holder", REQUIRED, HOLDERS)
    if "shape" in table and "inertia_kg_m2" in table:
        raise table.error(None, "give either shape or inertia_kg_m2, not both")
    if "inertia_kg_m2" in table:
        inertia = _inertia_matrix(table, mass)
    elif "shape" in table:
        inertia = _shape_inertia(table, mass)
    else:
        inertia = np.zeros((3, 3))  # a point mass
    source = table.text("source", "")
    retreat = None if "retreat" not in table else parse_retreat(table.raw("retreat"), path, f"{task}.retreat")
    shape = dict(table.raw("shape")) if "shape" in table else None
    return TaskObject(task, mass, com, inertia, holder, source, retreat, shape)


def load_objects(path: str | Path | None = None) -> ObjectTable:
    """Read and validate a task file (``None``: the shipped :data:`DEFAULT_OBJECTS`), through the
    bounded reader of every settings file (:func:`ipromp_pin.inputs.load_toml`: a regular file of at
    most 1 MB, nested not too deeply).

    Raises:
        RobotError: unreadable, special or oversized file, bad TOML, an unknown key (naming the known
            one it resembles) or a bad field (a mass, size or centre of mass outside its plausible
            range, an inertia that is not symmetric, not positive definite or violates the triangle
            inequality, an unknown holder or shape), naming the file, the field and the problem.
    """
    p = DEFAULT_OBJECTS if path is None else Path(path)
    error = field_errors(RobotError, p)
    try:
        doc = load_toml(p, "task", lambda problem: error(None, problem))
    except OSError as exc:
        raise error(None, f"cannot read the task file: {exc.strerror or exc}") from None
    version = doc.pop("schema_version", 1)
    if version != 1 or isinstance(version, bool):
        raise error("schema_version", f"unsupported version {version!r} (this code reads 1)")
    return ObjectTable(p, {task: _task_object(task, table, p, error) for task, table in doc.items()})
