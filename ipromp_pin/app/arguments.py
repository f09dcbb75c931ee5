"""Argument helpers shared by the commands: the parser whose errors are one line, number and port
types, help strings whose "(default ...)" is read from the settings' own defaults, the pipeline
overrides of ``run``, ``replay`` and ``preview``, and the closed-loop options of ``replay`` and
``evaluate --closed-loop``.

Nothing here imports the scientific stack at import time: the defaults a help string shows are
read when the help is printed (:func:`show_default`).
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import math
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from .progress import progress

if TYPE_CHECKING:
    from ..data import Dataset
    from ..planning.closed_loop import ClosedLoopSettings
    from ..robot import Robot
    from .config import PipelineConfig

MAX_WINDOW_S = 600.0
"""Longest observation window in seconds the command line takes (``--until-s``, ``--window-s``): the
upper bound of :data:`ipromp_pin.data.WINDOW_RANGE_S` (not imported here: ``--help`` answers without
the scientific stack)."""

DEFAULT_MARK = "{default}"
"""Where a help string shows the default that :func:`show_default` attached to its option."""


class HelpFormatter(argparse.HelpFormatter):
    """Help formatter that replaces :data:`DEFAULT_MARK` by the option's default, read from its
    source (the settings' dataclass fields) only when the help is printed."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = super()._get_help_string(action)
        source = getattr(action, "default_source", None)
        if text is None or source is None:
            return text
        return text.replace(DEFAULT_MARK, format_default(source()))


def format_default(value: Any) -> str:
    """A default as a help string shows it: numbers with ``:g``, ``None`` (the model's own) as ``model``."""
    if value is None:
        return "model"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def show_default(action: argparse.Action, source: Callable[[], Any]) -> argparse.Action:
    """Attach the source of the default that ``action``'s help shows at :data:`DEFAULT_MARK`."""
    action.default_source = source  # type: ignore[attr-defined]
    return action


def config_default(name: str) -> Callable[[], Any]:
    """The source of the pipeline field ``name``'s default (``"observation.ratio"``)."""

    def source() -> Any:
        from .config import default_of

        return default_of(name)

    return source


def closed_loop_default(name: str) -> Callable[[], Any]:
    """The source of the default of ``ClosedLoopSettings`` field ``name`` (``planning.closed_loop``)."""

    def source() -> Any:
        from ..planning.closed_loop import ClosedLoopSettings

        return getattr(ClosedLoopSettings(), name)

    return source


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit status 2), like every other input error;
    its help shows the defaults of :func:`show_default`."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self.commands: dict[str, argparse.ArgumentParser] = {}
        """The parsers of the sub-commands (:meth:`add_subparsers`), by name."""

    def add_subparsers(self, **kwargs: Any) -> Any:
        """argparse's sub-commands, remembered so that an unknown option is reported by its command."""
        action = super().add_subparsers(**kwargs)
        self.commands = action.choices
        return action

    def parse_args(self, args: Any = None, namespace: Any = None) -> argparse.Namespace:  # type: ignore[override]
        """argparse's, an unknown option reported by the command's parser with the closest option."""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self.commands.get(getattr(parsed, "command", None) or "", self)
            names = list(getattr(parser, "_option_string_actions", {}))
            hints = [(x, close[0]) for x in extras if (close := closest_option(x, names))]
            if len(hints) == 1:
                hint = f"; did you mean {hints[0][1]}?"
            else:
                hint = "".join(f"; {given}: did you mean {name}?" for given, name in hints)
            parser.error(f"unrecognized arguments: {' '.join(extras)}{hint}")
        return parsed

    def error(self, message: str) -> NoReturn:
        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:
            close = difflib.get_close_matches(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)), n=1)
            if close:
                message = message.replace(" (choose from", f"; did you mean '{close[0]}'? (choose from", 1)
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def closest_option(given: str, names: list[str]) -> list[str]:
    """The option of ``names`` closest to the unknown ``given`` (``--tsk`` -> ``--task``; an
    ``--opt=value`` compared by its name), or ``[]`` when none is close or ``given`` is no option."""
    if not given.startswith("-"):
        return []
    return difflib.get_close_matches(given.split("=", 1)[0], names, n=1, cutoff=0.75)


def port(text: str) -> int:
    """An argparse type: a TCP port number, 1-65535."""
    try:
        number = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 1 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"port {number} is outside 1-65535")
    return number


def bounded(kind: type, low: float, high: float | None = None, *, open_low: bool = False):
    """An argparse type: a finite ``kind`` number in [low, high] (``(low, high]`` with ``open_low``)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        ok = math.isfinite(value) and (value > low if open_low else value >= low)
        if not ok or (high is not None and value > high):
            lo = f"({low:g}" if open_low else f"[{low:g}"
            raise argparse.ArgumentTypeError(
                f"{value!r} is outside {lo}, {'inf' if high is None else f'{high:g}'}]"
            )
        return value

    return parse


def add_pipeline_overrides(p: argparse.ArgumentParser, ratio: bool = True) -> None:
    """The options of ``run``, ``replay`` and ``preview`` that override the pipeline definition's values."""
    p.add_argument(
        "pipeline",
        type=Path,
        help="pipeline definition (TOML), e.g. pipelines/baxter_handover.toml, or the name of a shipped one, "
        "e.g. baxter_handover (used when no file of that name is in the current folder)",
    )
    p.add_argument("--out", type=Path, help="output folder (default: the pipeline's outputs.dir)")
    p.add_argument("--dataset", type=Path, help="dataset folder (default: built-in synthetic demos)")
    p.add_argument("--format", help="dataset format: auto, chen2017, multimodal, bag, native")
    p.add_argument("--frames", help="comma-separated skeleton frames to read, e.g. /left_hand_1")
    p.add_argument("--observe", help="comma-separated observed groups, e.g. orientation,emg")
    p.add_argument("--task", help="task of the demo to observe (default: the first task)")
    show_default(
        p.add_argument(
            "--demo",
            type=int,
            help=f"index of the demo in its task, held out of training (default {DEFAULT_MARK})",
        ),
        config_default("observation.demo"),
    )
    if ratio:
        window = p.add_mutually_exclusive_group()
        show_default(
            window.add_argument(
                "--ratio",
                type=bounded(float, 0.0, 1.0, open_low=True),
                help=f"observed fraction of the motion, in (0, 1] (default {DEFAULT_MARK}; offline: the "
                "motion's length is known once it is over)",
            ),
            config_default("observation.ratio"),
        )
        window.add_argument(
            "--until-s",
            type=bounded(float, 0.0, MAX_WINDOW_S, open_low=True),
            metavar="S",
            help=f"observe the first S seconds of the motion instead, in (0, {MAX_WINDOW_S:g}] (the "
            "pipeline's [observation] until_s)",
        )
    p.add_argument("--model", type=Path, help="use this saved model instead of training")
    p.add_argument("--save-model", type=Path, help="save the trained model here")
    p.add_argument(
        "--retrain",
        action="store_true",
        help="train even if an earlier run trained a model on the same demos and settings",
    )
    p.add_argument("--robot", help="robot settings file or shipped name (default: the pipeline's)")
    p.add_argument(
        "--objects",
        type=Path,
        help="task file of the objects the gripper holds (default: the pipeline's [robot] objects, else the "
        "shipped robots/objects.toml; docs/objects.md)",
    )
    show_default(
        p.add_argument(
            "--rate", type=float, help=f"output control rate in [Hz], in [1, 1000] (default {DEFAULT_MARK})"
        ),
        config_default("timing.control_rate_hz"),
    )


def pipeline_config(args: argparse.Namespace) -> PipelineConfig:
    """The pipeline definition ``args.pipeline`` with the command line's overrides (validated)."""
    from ..data import parse_groups
    from .config import load_pipeline

    return load_pipeline(
        args.pipeline,
        options=PIPELINE_OPTIONS,
        out_dir=args.out,
        dataset=args.dataset,
        format=args.format,
        frames=parse_groups(args.frames) if args.frames else None,
        observe=parse_groups(args.observe) if args.observe else None,
        task=args.task,
        demo=args.demo,
        ratio=getattr(args, "ratio", None),
        until_s=getattr(args, "until_s", None),
        load_model=args.model,
        save_model=args.save_model,
        model_cache=False if getattr(args, "retrain", False) else None,
        robot=args.robot,
        objects=getattr(args, "objects", None),
        retreat=False if getattr(args, "no_retreat", False) else None,
        control_rate_hz=args.rate,
        preview_html=False if getattr(args, "no_preview", False) else None,
        plots=True if getattr(args, "plots", False) else None,
        ros=getattr(args, "ros", None),
        rosbag=False if getattr(args, "no_rosbag", False) else None,
        ros1_bag=True if getattr(args, "ros1_bag", False) else None,
    )


PIPELINE_OPTIONS = {
    "out_dir": "--out",
    "dataset": "--dataset",
    "format": "--format",
    "frames": "--frames",
    "observe": "--observe",
    "task": "--task",
    "demo": "--demo",
    "ratio": "--ratio",
    "load_model": "--model",
    "save_model": "--save-model",
    "robot": "--robot",
    "objects": "--objects",
    "control_rate_hz": "--rate",
    "ros": "--ros",
}
"""The pipeline's flat names (:class:`~ipromp_pin.app.config.PipelineConfig`) and the options of
:func:`add_pipeline_overrides` that set them: an error about such a value names the option."""


def add_closed_loop_options(p: argparse.ArgumentParser) -> None:
    """The closed-loop options of ``replay`` and ``evaluate --closed-loop``."""
    p.add_argument(
        "--limits",
        default="demonstrated",
        help="limit profile: demonstrated (from the training demos, default), conservative (robot settings) "
        "or a profile file (TOML, e.g. a replay's limits.toml)",
    )
    show_default(
        p.add_argument(
            "--condition-noise",
            default=None,
            help="noise ratio with which the closed loop conditions the robot trajectory: a positive number, "
            f"or model for the model's own (default {DEFAULT_MARK}, chosen by cross-validation of the "
            "closed loop)",
        ),
        closed_loop_default("condition_noise"),
    )
    p.add_argument(
        "--handover-estimates",
        choices=["on", "off"],
        default=None,
        help="whether every re-plan also applies the model's hand-over estimates (hand-over regression, "
        "orientation estimate) as the one-shot plan does (default off: they made the arrival later, "
        "docs/closed_loop.md)",
    )
    p.add_argument(
        "--unknown-task",
        choices=["hold", "ignore"],
        default=None,
        help="what the robot does while the observation matches none of the model's tasks: hold (default: "
        "it does not start, and once started it stops, holds and, still unknown, retreats to its rest "
        "configuration) or ignore (acts on the most probable task)",
    )
    show_default(
        p.add_argument(
            "--unknown-hold",
            type=float,  # checked with the other closed-loop settings (one line naming unknown_hold_s)
            metavar="S",
            help="with --unknown-task hold: seconds the robot holds at rest after stopping on an unknown "
            f"observation before it retreats (default {DEFAULT_MARK})",
        ),
        closed_loop_default("unknown_hold_s"),
    )
    show_default(
        p.add_argument("--replan-rate", type=float, help=f"re-plan rate in [Hz] (default {DEFAULT_MARK})"),
        closed_loop_default("replan_rate_hz"),
    )
    show_default(
        p.add_argument(
            "--blend", type=float, help=f"blend horizon in [s] of a re-plan (default {DEFAULT_MARK})"
        ),
        closed_loop_default("blend_s"),
    )
    p.add_argument(
        "--start-confidence",
        type=float,  # checked with the other closed-loop settings (one line naming start_confidence)
        metavar="P",
        help="the robot also starts as soon as a task is recognised with posterior P, in (0, 1] "
        "(default: by time alone)",
    )
    show_default(
        p.add_argument(
            "--freeze-phase",
            type=float,
            help="stop re-planning once this fraction of the predicted motion is observed, in (0, 1] "
            f"(default {DEFAULT_MARK})",
        ),
        closed_loop_default("freeze_phase"),
    )


def closed_loop_settings(args: argparse.Namespace, **given: float | None) -> ClosedLoopSettings:
    """The closed-loop settings of the command line: :class:`ClosedLoopSettings`' defaults with the
    options given (and the values of ``given`` that are not ``None``, e.g. ``control_rate_hz``),
    validated once (one-line errors naming the field)."""
    from ..planning.closed_loop import ClosedLoopSettings

    options: dict[str, Any] = {
        "replan_rate_hz": args.replan_rate,
        "blend_s": args.blend,
        "freeze_phase": args.freeze_phase,
        "start_confidence": args.start_confidence,
        "unknown_hold_s": getattr(args, "unknown_hold", None),
        **given,
    }
    chosen = {name: value for name, value in options.items() if value is not None}
    if getattr(args, "handover_estimates", None) is not None:
        chosen["handover_estimates"] = args.handover_estimates == "on"
    if getattr(args, "unknown_task", None) is not None:
        chosen["require_known"] = args.unknown_task == "hold"
    if args.condition_noise is not None:  # None in the settings: the model's own
        try:
            chosen["condition_noise"] = (
                None if args.condition_noise == "model" else float(args.condition_noise)
            )
        except ValueError:
            chosen["condition_noise"] = args.condition_noise  # validate() names the field
    return dataclasses.replace(ClosedLoopSettings(), **chosen).validate("command line")


def add_strict_human(p: argparse.ArgumentParser) -> None:
    """Add ``--strict-human`` to a planning command's parser."""
    p.add_argument(
        "--strict-human",
        action="store_true",
        help="refuse (exit status 3) when the model's human model is known not to fit its training "
        "demonstrations (default: a warning; docs/human_model.md)",
    )


def read_dataset(args: argparse.Namespace, frames, robot: Robot, timed: bool = False) -> Dataset:
    """The dataset ``args.dataset`` (``args.format``), its arm joints and limits those of ``robot``,
    with a progress line (and, when ``timed``, a line saying what was read in how long)."""
    from ..robot.recordings import read_recordings

    t0 = time.perf_counter()
    ds = read_recordings(args.dataset, robot, format=args.format, frames=frames, progress=progress())
    if timed:
        print(
            f"read {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.1f} s"
        )
    return ds
