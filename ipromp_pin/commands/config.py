"""Pipeline definitions: the TOML file that says what ``ipromp-pin run`` and ``preview`` do.

A pipeline definition is a TOML file (see ``pipelines/baxter_handover.toml``) with the sections
``[data]``, ``[model]``, ``[observation]``, ``[robot]``, ``[timing]`` and ``[outputs]``; relative
paths in it, ``outputs.dir`` included, are relative to its folder (an empty ``outputs.dir``, the
shipped default, means ``out`` in the current folder, so that a shipped definition never writes
into the installed package). :func:`load_pipeline` reads and validates it into a
:class:`PipelineConfig`; command-line overrides replace single values (paths given on the command
line are relative to the current folder).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from ..data import ROBOT
from ..exceptions import PipelineError
from ..shipped import PIPELINES_DIR

_SCHEMA: dict[str, dict[str, type | tuple[type, ...]]] = {
    "data": {"dataset": str, "format": str, "rate_hz": (int, float), "frames": list, "synthetic_seed": int},
    "model": {"observe": list, "load": str, "save": str, "cache": bool},
    "observation": {"task": str, "demo": int, "ratio": (int, float)},
    "robot": {"settings": str},
    "timing": {"control_rate_hz": (int, float)},
    "outputs": {
        "dir": str,
        "preview_html": bool,
        "plots": bool,
        "ros": int,
        "rosbag": bool,
        "ros1_bag": bool,
    },
}

RATE_RANGE_HZ = (1.0, 1000.0)
"""Plausible sampling rates in [Hz] of the aligned streams (``data.rate_hz``; the recordings run at
50-100 Hz) and of the output trajectory (``timing.control_rate_hz``; Baxter's joint command loop
runs at 100 Hz, the fastest common arms at 1 kHz). Outside it a run would allocate absurd arrays."""

DEFAULT_OUT_DIR = Path("out")
"""Output folder when neither the pipeline file nor the command line names one (current folder)."""


@dataclass
class PipelineConfig:
    """A validated pipeline definition.

    Attributes:
        source: The definition file (or ``"<defaults>"``).
        dataset: Dataset folder; ``None`` uses the built-in synthetic demos.
        format: Reader format (``auto``, ``chen2017``, ``multimodal``, ``bag``, ``native``).
        rate_hz: Common sampling rate of the aligned streams, in [Hz].
        frames: Skeleton frames to read (multimodal data).
        synthetic_seed: Seed of the synthetic demos.
        observe: Observed human channel groups.
        load_model: A saved model file to use instead of training.
        save_model: Where to save the trained model.
        model_cache: Reuse the model an earlier run trained on the same demos with the same settings
            (kept in the user's cache folder, see :mod:`ipromp_pin.commands.model_cache`).
        task: Task of the observed demo (``None``: the first task).
        demo: Index of the observed demo within its task (negative counts from the end).
        ratio: Observed fraction of the human's motion, in (0, 1].
        robot: Robot settings file or name.
        control_rate_hz: Output trajectory sampling rate, in [Hz].
        out_dir: Output folder (relative to the pipeline file's folder when the file names it).
        preview_html: Write ``preview.html``.
        plots: Write PNG figures.
        ros: ROS version of ``trajectory.json``'s message (2: ``sec``/``nanosec``; 1: ``secs``/``nsecs``).
        rosbag: Write the rosbag2 folder ``rosbag/`` (MCAP storage).
        ros1_bag: Also write the ROS 1 bag ``run.bag``.
    """

    source: str = "<defaults>"
    dataset: Path | None = None
    format: str = "auto"
    rate_hz: float = 50.0
    frames: list[str] = field(default_factory=list)
    synthetic_seed: int = 0
    observe: list[str] = field(default_factory=lambda: ["orientation", "emg"])
    load_model: Path | None = None
    save_model: Path | None = None
    model_cache: bool = True
    task: str | None = None
    demo: int = -1
    ratio: float = 0.2
    robot: str = "baxter_left"
    control_rate_hz: float = 100.0
    out_dir: Path = DEFAULT_OUT_DIR
    preview_html: bool = True
    plots: bool = False
    ros: int = 2
    rosbag: bool = True
    ros1_bag: bool = False

    def validate(self) -> PipelineConfig:
        """Check value ranges; raise :class:`PipelineError` naming the field."""
        if not (0.0 < self.ratio <= 1.0):
            raise PipelineError(
                f"{self.source}: field 'observation.ratio': must be in (0, 1], got {self.ratio}"
            )
        if not self.observe:
            raise PipelineError(f"{self.source}: field 'model.observe': no channel group given")
        if ROBOT in self.observe:
            raise PipelineError(f"{self.source}: field 'model.observe': the robot group cannot be observed")
        if self.ros not in (1, 2):
            raise PipelineError(f"{self.source}: field 'outputs.ros': must be 1 or 2, got {self.ros}")
        lo, hi = RATE_RANGE_HZ
        for name, value in (("data.rate_hz", self.rate_hz), ("timing.control_rate_hz", self.control_rate_hz)):
            if not (np.isfinite(value) and lo <= value <= hi):
                raise PipelineError(
                    f"{self.source}: field '{name}': must be a rate in [{lo:g}, {hi:g}] Hz, got {value}"
                )
        if self.synthetic_seed < 0:
            raise PipelineError(
                f"{self.source}: field 'data.synthetic_seed': must be >= 0, got {self.synthetic_seed}"
            )
        if not isinstance(self.demo, int) or isinstance(self.demo, bool) or abs(self.demo) > 10**9:
            raise PipelineError(
                f"{self.source}: field 'observation.demo': must be an index, got {self.demo!r}"
            )
        for name, items in (("data.frames", self.frames), ("model.observe", self.observe)):
            if not all(isinstance(x, str) and x for x in items):
                raise PipelineError(
                    f"{self.source}: field '{name}': must list non-empty names, got {items!r}"
                )
        if len(set(self.observe)) != len(self.observe):
            raise PipelineError(
                f"{self.source}: field 'model.observe': a group is listed twice in {self.observe}"
            )
        return self


def resolve_pipeline_path(path_or_name: str | Path) -> Path:
    """The pipeline file to read: ``path_or_name`` if it is a file, else, for a bare name such as
    ``"baxter_handover"``, the shipped definition of that name (:data:`ipromp_pin.shipped.PIPELINES_DIR`).

    A name that matches neither is returned unchanged (:func:`load_pipeline` reports it as not found).
    """
    path = Path(path_or_name)
    if not path.is_file() and path.suffix == "" and len(path.parts) == 1:
        shipped = PIPELINES_DIR / f"{path.name}.toml"
        if shipped.is_file():
            return shipped
    return path


def load_pipeline(path: str | Path, **overrides) -> PipelineConfig:
    """Read a pipeline definition; ``overrides`` (non-``None`` values) replace its fields.

    Args:
        path: A pipeline file, or the name of a shipped one (see :func:`resolve_pipeline_path`).
        **overrides: Field values that replace the file's.

    Raises:
        PipelineError: unreadable file, unknown section or key, wrong type or value.
    """
    path = resolve_pipeline_path(path)
    if path.is_dir():
        raise PipelineError(f"{path}: is a folder, not a pipeline file (e.g. pipelines/baxter_handover.toml)")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        known = ", ".join(sorted(f.stem for f in PIPELINES_DIR.glob("*.toml"))) or "none"
        raise PipelineError(f"{path}: pipeline file not found (shipped pipelines: {known})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise PipelineError(f"{path}: not a valid TOML pipeline file: {exc}") from None
    except OSError as exc:
        raise PipelineError(f"{path}: cannot read the pipeline file: {exc.strerror or exc}") from None
    for section, table in doc.items():
        if section not in _SCHEMA:
            raise PipelineError(f"{path}: unknown section [{section}] (known: {', '.join(_SCHEMA)})")
        if not isinstance(table, dict):
            raise PipelineError(f"{path}: field '{section}': expected a table")
        for key, value in table.items():
            kind = _SCHEMA[section].get(key)
            if kind is None:
                raise PipelineError(f"{path}: field '{section}.{key}': unknown key")
            if not isinstance(value, kind) or (kind in (int, (int, float)) and isinstance(value, bool)):
                raise PipelineError(f"{path}: field '{section}.{key}': wrong type {type(value).__name__}")
            if kind is list and not all(isinstance(x, str) and x for x in value):
                raise PipelineError(
                    f"{path}: field '{section}.{key}': must be a list of names, got {value!r}"
                )
    base = path.resolve().parent

    def get(section: str, key: str, default):
        return doc.get(section, {}).get(key, default)

    def rel(value: str) -> Path | None:
        if not value:
            return None
        p = Path(value).expanduser()
        return p if p.is_absolute() else base / p

    robot = get("robot", "settings", "baxter_left")
    if "/" in robot or robot.endswith(".toml"):
        robot = str(rel(robot))
    cfg = PipelineConfig(
        source=str(path),
        dataset=rel(get("data", "dataset", "")),
        format=get("data", "format", "auto"),
        rate_hz=float(get("data", "rate_hz", 50.0)),
        frames=[str(f) for f in get("data", "frames", [])],
        synthetic_seed=int(get("data", "synthetic_seed", 0)),
        observe=[str(g) for g in get("model", "observe", ["orientation", "emg"])],
        load_model=rel(get("model", "load", "")),
        save_model=rel(get("model", "save", "")),
        model_cache=bool(get("model", "cache", True)),
        task=get("observation", "task", "") or None,
        demo=int(get("observation", "demo", -1)),
        ratio=float(get("observation", "ratio", 0.2)),
        robot=robot,
        control_rate_hz=float(get("timing", "control_rate_hz", 100.0)),
        out_dir=rel(get("outputs", "dir", "")) or DEFAULT_OUT_DIR,
        preview_html=bool(get("outputs", "preview_html", True)),
        plots=bool(get("outputs", "plots", False)),
        ros=int(get("outputs", "ros", 2)),
        rosbag=bool(get("outputs", "rosbag", True)),
        ros1_bag=bool(get("outputs", "ros1_bag", False)),
    )
    names = {f.name for f in fields(PipelineConfig)}
    for key, value in overrides.items():
        if key not in names:
            raise PipelineError(f"unknown pipeline override '{key}'")
        if value is not None:
            setattr(cfg, key, value)
    return cfg.validate()
