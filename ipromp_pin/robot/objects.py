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

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..shipped import ROBOTS_DIR
from .model import Robot
from .retreat_target import RetreatTarget, check_retreat_robot, parse_retreat
from .settings import settings_error

DEFAULT_OBJECTS = ROBOTS_DIR / "objects.toml"
"""The shipped task file (assumed objects of the shared recordings' tasks and the synthetic ones)."""

HOLDERS = ("robot_gives", "robot_receives")
"""``robot_gives``: the robot holds the object until the hand-over; ``robot_receives``: from it on."""

MAX_COM_DISTANCE_M = 1.0
"""Largest distance of an object's centre of mass from the gripper frame's origin [m]."""

_KEYS = {"mass_kg", "com_m", "holder", "shape", "inertia_kg_m2", "source", "retreat"}


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


def _number(value: object, path: Path, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise settings_error(path, name, f"must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise settings_error(path, name, f"must be finite, got {out}")
    return out


def _positive(value: object, path: Path, name: str) -> float:
    out = _number(value, path, name)
    if out <= 0:
        raise settings_error(path, name, f"must be positive, got {out}")
    return out


def _shape_inertia(shape: object, mass: float, path: Path, name: str) -> np.ndarray:
    if not isinstance(shape, dict):
        raise settings_error(path, name, "must be a table (kind = 'box' or 'cylinder')")
    kind = shape.get("kind")
    if kind == "box":
        size = shape.get("size_m")
        if not isinstance(size, list) or len(size) != 3:
            raise settings_error(path, f"{name}.size_m", "must be a list of 3 edge lengths [m]")
        return box_inertia(mass, np.array([_positive(v, path, f"{name}.size_m") for v in size]))
    if kind == "cylinder":
        radius = _positive(shape.get("radius_m"), path, f"{name}.radius_m")
        length = _positive(shape.get("length_m"), path, f"{name}.length_m")
        axis = shape.get("axis", "z")
        if axis not in ("x", "y", "z"):
            raise settings_error(path, f"{name}.axis", f"must be 'x', 'y' or 'z', got {axis!r}")
        return cylinder_inertia(mass, radius, length, "xyz".index(axis))
    raise settings_error(path, f"{name}.kind", f"must be 'box' or 'cylinder', got {kind!r}")


def _inertia_matrix(value: object, mass: float, path: Path, name: str) -> np.ndarray:
    if not (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(r, list) and len(r) == 3 for r in value)
    ):
        raise settings_error(path, name, "must be a 3 x 3 list of lists [kg m^2]")
    inertia = np.array([[_number(v, path, name) for v in row] for row in value])
    if not np.allclose(inertia, inertia.T, atol=1e-12):
        raise settings_error(path, name, "must be symmetric")
    eig = np.linalg.eigvalsh(inertia)
    if mass > 0 and eig[0] <= 0:
        raise settings_error(path, name, f"must be positive definite (eigenvalues {eig.round(9).tolist()})")
    if eig[0] < 0:
        raise settings_error(path, name, f"must be positive semi-definite (eigenvalues {eig.tolist()})")
    return inertia


def _task_object(task: str, table: object, path: Path) -> TaskObject:
    if not isinstance(table, dict):
        raise settings_error(path, task, "must be a table (mass_kg, com_m, holder, shape or inertia_kg_m2)")
    for key in table:
        if key not in _KEYS:
            raise settings_error(path, f"{task}.{key}", f"unknown key (known: {', '.join(sorted(_KEYS))})")
    if "mass_kg" not in table:
        raise settings_error(path, f"{task}.mass_kg", "missing")
    mass = _number(table["mass_kg"], path, f"{task}.mass_kg")
    if mass < 0:
        raise settings_error(path, f"{task}.mass_kg", f"must be >= 0, got {mass}")
    com_raw = table.get("com_m", [0.0, 0.0, 0.0])
    if not isinstance(com_raw, list) or len(com_raw) != 3:
        raise settings_error(path, f"{task}.com_m", "must be a list of 3 numbers [m]")
    com = np.array([_number(v, path, f"{task}.com_m") for v in com_raw])
    if np.linalg.norm(com) > MAX_COM_DISTANCE_M:
        raise settings_error(
            path,
            f"{task}.com_m",
            f"{np.linalg.norm(com):.3f} m from the gripper (at most {MAX_COM_DISTANCE_M} m)",
        )
    holder = table.get("holder")
    if holder not in HOLDERS:
        raise settings_error(path, f"{task}.holder", f"must be one of {', '.join(HOLDERS)}, got {holder!r}")
    if "shape" in table and "inertia_kg_m2" in table:
        raise settings_error(path, task, "give either shape or inertia_kg_m2, not both")
    if "inertia_kg_m2" in table:
        inertia = _inertia_matrix(table["inertia_kg_m2"], mass, path, f"{task}.inertia_kg_m2")
    elif "shape" in table:
        inertia = _shape_inertia(table["shape"], mass, path, f"{task}.shape")
    else:
        inertia = np.zeros((3, 3))  # a point mass
    source = table.get("source", "")
    if not isinstance(source, str):
        raise settings_error(path, f"{task}.source", "must be a string")
    retreat = None if "retreat" not in table else parse_retreat(table["retreat"], path, f"{task}.retreat")
    shape = dict(table["shape"]) if "shape" in table else None
    return TaskObject(task, mass, com, inertia, str(holder), source, retreat, shape)


def load_objects(path: str | Path | None = None) -> ObjectTable:
    """Read and validate a task file (``None``: the shipped :data:`DEFAULT_OBJECTS`).

    Raises:
        RobotError: unreadable file, bad TOML, or a bad field (negative or non-finite mass, a centre of
            mass more than :data:`MAX_COM_DISTANCE_M` from the gripper, an inertia that is not positive
            definite, an unknown holder or key), naming the file, the field and the problem.
    """
    p = DEFAULT_OBJECTS if path is None else Path(path)
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise settings_error(p, None, f"not a valid TOML task file: {exc}") from None
    except OSError as exc:
        raise settings_error(p, None, f"cannot read the task file: {exc.strerror or exc}") from None
    version = doc.pop("schema_version", 1)
    if version != 1:
        raise settings_error(p, "schema_version", f"unsupported version {version!r} (this code reads 1)")
    return ObjectTable(p, {task: _task_object(task, table, p) for task, table in doc.items()})
