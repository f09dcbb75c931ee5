"""Pipeline definitions: the TOML file that says what ``ipromp-pin run`` and ``preview`` do.

A pipeline definition is a TOML file (see ``pipelines/baxter_handover.toml``) with the sections
``[data]``, ``[model]``, ``[observation]``, ``[robot]``, ``[timing]`` and ``[outputs]``; relative
paths in it, ``outputs.dir`` included, are relative to its folder (an empty ``outputs.dir``, the
shipped default, means ``out`` in the current folder, so that a shipped definition never writes
into the installed package). :func:`load_pipeline` reads and validates it into a
:class:`PipelineConfig`; command-line overrides replace single values (paths given on the command
line are relative to the current folder).

Each section is a typed dataclass (:class:`DataConfig`, :class:`ModelConfig`,
:class:`ObservationConfig`, :class:`RobotConfig`, :class:`TimingConfig`, :class:`OutputsConfig`):
its fields are the one source of the TOML schema (keys and types, :func:`schema`), of the
defaults (:func:`default_of`, which the command line's help strings show) and of the field names
in error messages (``'observation.ratio'``). A field typed ``Path`` or ``str | None`` is a string
in the file, where an empty string means the field's default.
"""

from __future__ import annotations

import tomllib
import typing
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from ..data import ROBOT, WINDOW_RANGE_S, ObservationWindow
from ..exceptions import PipelineError
from ..fields import Range, check_keys, field_errors
from ..inputs import load_toml
from ..shipped import DEFAULT_ROBOT, PIPELINES_DIR

RATE_RANGE = Range(
    1.0,
    1000.0,
    "Hz",
    "the recordings run at 50-100 Hz, Baxter's joint command loop at 100 Hz, the fastest common arms' "
    "at 1 kHz",
)
"""Plausible sampling rates of the aligned streams (``data.rate_hz``) and of the output trajectory
(``timing.control_rate_hz``). Outside it a run would allocate absurd arrays."""

RATE_RANGE_HZ = (RATE_RANGE.lo, RATE_RANGE.hi)
""":data:`RATE_RANGE`'s bounds in [Hz]."""

RATIO_RANGE = Range(0.0, 1.0, "", "a fraction of the human's motion", lo_open=True)
"""Plausible observed fractions (``observation.ratio``)."""

DEFAULT_OUT_DIR = Path("out")
"""Output folder when neither the pipeline file nor the command line names one (current folder)."""

T = TypeVar("T")


def _bad(source: str, section: str, key: str, problem: str) -> PipelineError:
    """The one-line error ``SOURCE: field 'SECTION.KEY': PROBLEM``."""
    return PipelineError(f"{source}: field '{section}.{key}': {problem}")


@dataclass
class DataConfig:
    """``[data]``: what is read.

    Attributes:
        dataset: Dataset folder (one sub-folder per task); ``None`` (empty in the file): the built-in
            synthetic demos.
        format: Reader format (``auto``, ``chen2017``, ``multimodal``, ``bag``, ``native``).
        rate_hz: Common sampling rate of the aligned streams, in [Hz].
        frames: Skeleton frames to read (multimodal data).
        synthetic_seed: Seed of the synthetic demos (>= 0).
    """

    SECTION: ClassVar[str] = "data"
    dataset: Path | None = None
    format: str = "auto"
    rate_hz: float = 50.0
    frames: list[str] = field(default_factory=list)
    synthetic_seed: int = 0


@dataclass
class ModelConfig:
    """``[model]``: the model that predicts.

    Attributes:
        observe: Observed human channel groups (orientation, emg, acc or a skeleton frame name).
        load: A saved model file to use instead of training (``None``: train).
        save: Where to save the trained model (``None``: don't).
        cache: Reuse the model an earlier run trained on the same demos with the same settings
            (kept in the user's cache folder, see :mod:`ipromp_pin.app.model_cache`).
    """

    SECTION: ClassVar[str] = "model"
    observe: list[str] = field(default_factory=lambda: ["orientation", "emg"])
    load: Path | None = None
    save: Path | None = None
    cache: bool = True


@dataclass
class ObservationConfig:
    """``[observation]``: which demo is observed, and how much of it.

    Attributes:
        task: Task of the observed demo (``None``: the first task).
        demo: Index of the observed demo within its task (held out of training; negative counts
            from the end).
        ratio: Observed fraction of the human's motion, in (0, 1] (offline: the motion's length is
            known once it is over).
        until_s: Observe the first ``until_s`` seconds of the human's motion instead, in (0, 600]
            (``None``: the ``ratio``); the file gives one or the other.
    """

    SECTION: ClassVar[str] = "observation"
    task: str | None = None
    demo: int = -1
    ratio: float = 0.2
    until_s: float | None = None


@dataclass
class RobotConfig:
    """``[robot]``: the robot whose part is planned.

    Attributes:
        settings: Robot settings: a shipped name (``robots/*.toml``) or a settings file path.
        objects: The task file of the objects the gripper holds (``None``: the shipped
            ``robots/objects.toml``; see ``docs/objects.md``).
        retreat: Plan, check and write the retreat after the hand-over of a task whose entry in the
            task file has one (``run``; ``--no-retreat``: False).
    """

    SECTION: ClassVar[str] = "robot"
    settings: str = DEFAULT_ROBOT
    objects: Path | None = None
    retreat: bool = True


@dataclass
class TimingConfig:
    """``[timing]``: the output trajectory's timing.

    Attributes:
        control_rate_hz: Output trajectory sampling rate, in [Hz].
    """

    SECTION: ClassVar[str] = "timing"
    control_rate_hz: float = 100.0


@dataclass
class OutputsConfig:
    """``[outputs]``: the files written.

    Attributes:
        dir: Output folder (relative to the pipeline file's folder when the file names it).
        preview_html: Write ``preview.html``.
        plots: Write PNG figures.
        ros: ROS version of ``trajectory.json``'s message (2: ``sec``/``nanosec``; 1: ``secs``/``nsecs``).
        rosbag: Write the rosbag2 folder ``rosbag/`` (MCAP storage).
        ros1_bag: Also write the ROS 1 bag ``run.bag``.
    """

    SECTION: ClassVar[str] = "outputs"
    dir: Path = DEFAULT_OUT_DIR
    preview_html: bool = True
    plots: bool = False
    ros: int = 2
    rosbag: bool = True
    ros1_bag: bool = False


SECTIONS: tuple[type[Any], ...] = (
    DataConfig,
    ModelConfig,
    ObservationConfig,
    RobotConfig,
    TimingConfig,
    OutputsConfig,
)
"""The section classes, in the order of the file and of the validation."""


@dataclass
class PipelineSections:
    """The sections of a pipeline definition, one attribute per TOML section."""

    data: DataConfig = field(default_factory=DataConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)
    outputs: OutputsConfig = field(default_factory=OutputsConfig)


def _kind(hint: Any) -> type | tuple[type, ...]:
    """The TOML type of a field annotated ``hint`` (paths and optional strings are strings)."""
    if hint is float or hint == float | None:
        return (int, float)
    if hint in (bool, int, str):
        return hint
    if typing.get_origin(hint) is list:
        return list
    return str  # Path, Path | None, str | None


def schema() -> dict[str, dict[str, type | tuple[type, ...]]]:
    """The TOML schema derived from the sections: ``{section: {key: type}}``."""
    return {
        cls.SECTION: {k: _kind(h) for k, h in typing.get_type_hints(cls).items() if k != "SECTION"}
        for cls in SECTIONS
    }


def _section_class(section: str) -> type[Any]:
    for cls in SECTIONS:
        if cls.SECTION == section:
            return cls
    raise KeyError(section)


def default_of(name: str) -> Any:
    """The default of field ``name`` (``"section.key"``, e.g. ``"observation.ratio"``)."""
    section, key = name.split(".")
    for f in fields(_section_class(section)):
        if f.name == key:
            return f.default if f.default_factory is MISSING else f.default_factory()
    raise KeyError(name)


class Flat(Generic[T]):
    """A flat attribute of :class:`PipelineConfig` (e.g. ``cfg.ratio``) that reads and writes the
    section field ``section.key`` (``observation.ratio``)."""

    def __init__(self, section: str, key: str) -> None:
        self.section, self.key = section, key

    def __get__(self, obj: PipelineConfig, owner: type | None = None) -> T:
        return getattr(getattr(obj.sections, self.section), self.key)

    def __set__(self, obj: PipelineConfig, value: T) -> None:
        setattr(getattr(obj.sections, self.section), self.key, value)


class PipelineConfig:
    """A validated pipeline definition: its :attr:`sections` (typed, one per TOML section) and flat
    attributes over them for the commands (``cfg.ratio`` is ``cfg.sections.observation.ratio``).

    ``PipelineConfig(ratio=0.3, ...)`` starts from the defaults and sets the flat attributes given.

    Attributes:
        source: The definition file (or ``"<defaults>"``).
        sections: The sections (:class:`PipelineSections`).
    """

    dataset = Flat[Path | None]("data", "dataset")
    format = Flat[str]("data", "format")
    rate_hz = Flat[float]("data", "rate_hz")
    frames = Flat[list[str]]("data", "frames")
    synthetic_seed = Flat[int]("data", "synthetic_seed")
    observe = Flat[list[str]]("model", "observe")
    load_model = Flat[Path | None]("model", "load")
    save_model = Flat[Path | None]("model", "save")
    model_cache = Flat[bool]("model", "cache")
    task = Flat[str | None]("observation", "task")
    demo = Flat[int]("observation", "demo")
    ratio = Flat[float]("observation", "ratio")
    until_s = Flat[float | None]("observation", "until_s")
    robot = Flat[str]("robot", "settings")
    objects = Flat[Path | None]("robot", "objects")
    retreat = Flat[bool]("robot", "retreat")
    control_rate_hz = Flat[float]("timing", "control_rate_hz")
    out_dir = Flat[Path]("outputs", "dir")
    preview_html = Flat[bool]("outputs", "preview_html")
    plots = Flat[bool]("outputs", "plots")
    ros = Flat[int]("outputs", "ros")
    rosbag = Flat[bool]("outputs", "rosbag")
    ros1_bag = Flat[bool]("outputs", "ros1_bag")

    def __init__(
        self, source: str = "<defaults>", sections: PipelineSections | None = None, **values: Any
    ) -> None:
        self.source = source
        self.sections = PipelineSections() if sections is None else sections
        self.options: dict[str, str] = {}
        """Flat name -> the command-line option that gave its value (``{"task": "--task"}``)."""
        self.update(**values)

    @classmethod
    def flat_names(cls) -> dict[str, str]:
        """The flat attribute names and the field each stands for: ``{"ratio": "observation.ratio"}``."""
        return {n: f"{v.section}.{v.key}" for n, v in vars(cls).items() if isinstance(v, Flat)}

    def where(self, name: str) -> str:
        """Where the value of the flat attribute ``name`` came from, as an error names it:
        ``command line: option '--task'`` or ``FILE: field 'observation.task'``."""
        if name in self.options:
            return f"command line: option '{self.options[name]}'"
        return f"{self.source}: field '{self.flat_names()[name]}'"

    def update(self, **values: Any) -> PipelineConfig:
        """Set the flat attributes given (``None`` values are skipped); an unknown name is an error."""
        names = self.flat_names()
        for key, value in values.items():
            if key not in names:
                raise PipelineError(f"unknown pipeline override '{key}'")
            if value is not None:
                setattr(self, key, value)
        return self

    def validate(self) -> PipelineConfig:
        """Check value ranges; raise :class:`PipelineError` naming the field (``'observation.ratio'``)."""

        def bad(name: str, problem: str) -> PipelineError:
            return PipelineError(f"{self.where(name)}: {problem}")

        if not RATIO_RANGE.contains(self.ratio):
            raise bad("ratio", f"must be in {RATIO_RANGE.text()}, got {self.ratio}")
        if self.until_s is not None and not WINDOW_RANGE_S.contains(self.until_s):
            span = WINDOW_RANGE_S
            raise bad("until_s", f"must be a time in {span.text()} ({span.source}), got {self.until_s}")
        if not self.observe:
            raise bad("observe", "no channel group given")
        if ROBOT in self.observe:
            raise bad("observe", "the robot group cannot be observed")
        if self.ros not in (1, 2):
            raise bad("ros", f"must be 1 or 2, got {self.ros}")
        for name in ("rate_hz", "control_rate_hz"):
            value = getattr(self, name)
            if not RATE_RANGE.contains(value):
                raise bad(name, f"must be a rate in {RATE_RANGE.text()} ({RATE_RANGE.source}), got {value}")
        if self.synthetic_seed < 0:
            raise bad("synthetic_seed", f"must be >= 0, got {self.synthetic_seed}")
        demo = self.demo
        if not isinstance(demo, int) or isinstance(demo, bool) or abs(demo) > 10**9:
            raise bad("demo", f"must be an index, got {demo!r}")
        for name in ("frames", "observe"):
            items = getattr(self, name)
            if not all(isinstance(x, str) and x for x in items):
                raise bad(name, f"must list non-empty names, got {items!r}")
        if len(set(self.observe)) != len(self.observe):
            raise bad("observe", f"a group is listed twice in {self.observe}")
        return self

    @property
    def window(self) -> ObservationWindow:
        """The observed window: the first ``until_s`` seconds when set, else the first ``ratio``."""
        if self.until_s is not None:
            return ObservationWindow(until_s=self.until_s)
        return ObservationWindow(ratio=self.ratio)

    def __repr__(self) -> str:
        return f"PipelineConfig(source={self.source!r}, sections={self.sections!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PipelineConfig):
            return NotImplemented
        return (self.source, self.sections) == (other.source, other.sections)


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


def _read_toml(path: Path) -> dict[str, Any]:
    if path.is_dir():
        raise PipelineError(f"{path}: is a folder, not a pipeline file (e.g. pipelines/baxter_handover.toml)")
    try:
        return load_toml(path, "pipeline", lambda problem: PipelineError(f"{path}: {problem}"))
    except FileNotFoundError:
        known = ", ".join(sorted(f.stem for f in PIPELINES_DIR.glob("*.toml"))) or "none"
        raise PipelineError(f"{path}: pipeline file not found (shipped pipelines: {known})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise PipelineError(f"{path}: not a valid TOML pipeline file: {exc}") from None
    except OSError as exc:
        raise PipelineError(f"{path}: cannot read the pipeline file: {exc.strerror or exc}") from None


def _check_types(path: Path, doc: dict[str, Any]) -> None:
    """Every section and key of ``doc`` known (else the known one it resembles), every value of its
    schema type."""
    known = schema()
    error = field_errors(PipelineError, path)
    check_keys(doc, known, "", error, what="section")
    for section, table in doc.items():
        if not isinstance(table, dict):
            raise error(section, "expected a table")
        check_keys(table, known[section], section, error)
        for key, value in table.items():
            kind = known[section][key]
            if not isinstance(value, kind) or (kind in (int, (int, float)) and isinstance(value, bool)):
                raise _bad(str(path), section, key, f"wrong type {type(value).__name__}")
            if isinstance(value, list) and not all(isinstance(x, str) and x for x in value):
                raise _bad(str(path), section, key, f"must be a list of names, got {value!r}")


def _section_from_table(cls: type[Any], table: dict[str, Any], base: Path) -> Any:
    """Section ``cls`` from its (type-checked) TOML table: missing keys take the field's default,
    relative paths are relative to ``base``, an empty string in a path or optional field is its default."""
    hints = typing.get_type_hints(cls)
    values: dict[str, Any] = {}
    for key, value in table.items():
        hint = hints[key]
        if hint is float or hint == float | None:
            value = float(value)
        elif typing.get_origin(hint) is list:
            value = [str(x) for x in value]
        elif hint is not str and isinstance(value, str):  # Path, Path | None, str | None
            if not value:
                continue
            if hint != str | None:
                value = _relative(value, base)
        elif cls is RobotConfig and key == "settings" and ("/" in value or value.endswith(".toml")):
            value = str(_relative(value, base))  # a settings file, not a shipped name
        values[key] = value
    return cls(**values)


def _relative(value: str, base: Path) -> Path:
    p = Path(value).expanduser()
    return p if p.is_absolute() else base / p


def load_pipeline(
    path: str | Path, options: dict[str, str] | None = None, **overrides: Any
) -> PipelineConfig:
    """Read a pipeline definition; ``overrides`` (non-``None`` values) replace its fields.

    Args:
        path: A pipeline file, or the name of a shipped one (see :func:`resolve_pipeline_path`).
        options: Flat name -> the command-line option that gave its override (``{"task": "--task"}``):
            errors about that value name the option instead of the file's field.
        **overrides: Values of :class:`PipelineConfig`'s flat attributes that replace the file's.

    The observed window is ``[observation] ratio`` or ``until_s``, never both; an override of either
    replaces the file's window (``ratio=`` clears the file's ``until_s``).

    Raises:
        PipelineError: unreadable file, unknown section or key, wrong type or value, a window given
            twice.
    """
    path = resolve_pipeline_path(path)
    doc = _read_toml(path)
    _check_types(path, doc)
    observation = doc.get(ObservationConfig.SECTION, {})
    if "ratio" in observation and "until_s" in observation:
        raise _bad(str(path), "observation", "until_s", "give ratio or until_s, not both")
    if overrides.get("ratio") is not None and overrides.get("until_s") is not None:
        raise PipelineError(f"{path}: observe a ratio or until_s seconds, not both")
    base = path.resolve().parent
    sections = PipelineSections(
        **{cls.SECTION: _section_from_table(cls, doc.get(cls.SECTION, {}), base) for cls in SECTIONS}
    )
    cfg = PipelineConfig(str(path), sections).update(**overrides)
    if overrides.get("ratio") is not None:  # the command line's fraction replaces the file's seconds
        cfg.until_s = None
    cfg.options = {k: v for k, v in (options or {}).items() if overrides.get(k) is not None}
    return cfg.validate()
