"""The application layer: ``ipromp-pin run | replay | evaluate | train | preview | calibrate | synth |
place``.

Stable interface (people script against it)::

    ipromp-pin run PIPELINE [--out DIR] [--dataset PATH] [--task T] [--demo I] [--ratio R] ...
    ipromp-pin replay PIPELINE [--dataset D --task T --demo I] --out DIR [--start-ratio R] [--limits L]
    ipromp-pin evaluate DATASET --protocol paper|splits --observe GROUPS --json FILE [--closed-loop]

Errors of the user's input exit with status 2 and a one-line message naming
the file, field and problem; no traceback. ``run`` exits with status 3 when the
planned motion fails its checks (it then writes no trajectory file unless
``--allow-failing-checks``). Progress lines are shown on a terminal only.

One module per command (:mod:`.run`, :mod:`.replay`, :mod:`.evaluate`, :mod:`.train`,
:mod:`.preview`, :mod:`.calibrate`, :mod:`.synth`, :mod:`.place`): its parser (``add_parser``), what
it runs (a typed request in, a typed outcome out) and its exit status (``main``). They share
:mod:`.arguments` (argument types, the pipeline overrides), :mod:`.config` (pipeline definitions),
:mod:`.session` (the set-up of the commands that plan on one held-out demo), :mod:`.progress` (the
progress line, one-line errors, exit codes), :mod:`.interrupt` (SIGINT / SIGTERM),
:mod:`.model_cache`. A command imports the modules that
compute when it runs (the scientific stack takes a second or two to import), so that ``--help``
and argument errors answer at once.
"""

from __future__ import annotations

from .interrupt import exit_quietly_while_starting

exit_quietly_while_starting()  # first: a Ctrl-C while the modules below load is one line, too

# ruff: noqa: E402 (the imports below come after the signal handlers above)
import argparse
import os
import sys

from ..exceptions import IPrompPinError, UnreachableError
from ..version import __version__
from . import calibrate, evaluate, place, plan, preview, replay, run, synth, train
from .arguments import OneLineErrorParser
from .interrupt import (
    EXIT_INTERRUPTED,
    ignore_late_signals,
    interruptible,
    interruption_behind,
    report_interruption,
)
from .progress import EXIT_CHECKS_FAILED, EXIT_ERROR, ProgressLine, print_error

__all__ = ["EXIT_CHECKS_FAILED", "EXIT_ERROR", "build_parser", "console_main", "main"]

COMMANDS = (run, train, plan, replay, evaluate, preview, calibrate, synth, place)
"""The command modules, in the order of ``ipromp-pin --help``; each adds its parser."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``ipromp-pin``."""
    parser = OneLineErrorParser(
        prog="ipromp-pin",
        description="EMG-augmented Interaction ProMPs: recognise a hand-over task, plan Baxter's part.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ipromp-pin`` console script. An interruption (SIGINT, SIGTERM) at any
    stage ends it with one line and exit status 130 or 143 (:mod:`~ipromp_pin.app.interrupt`)."""
    seen: list[str] = []  # the command, once parsed (for the interruption line)
    with interruptible():
        try:
            return _main(argv, seen)
        except KeyboardInterrupt as exc:  # SIGINT, or SIGTERM (Terminated)
            ProgressLine.end()
            return report_interruption(seen[-1] if seen else "", exc)
        except Exception as exc:  # raised *because* of an interruption (a library's handler, a kernel)
            cause = interruption_behind(exc)
            if cause is None:
                raise
            ProgressLine.end()
            return report_interruption(seen[-1] if seen else "", cause)


def _main(argv: list[str] | None, seen: list[str]) -> int:
    """Parse ``argv`` and run its command (appended to ``seen``); the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    seen.append(args.command)
    # The kernels: for the short commands, the compiled ones when cached, else their numpy version
    # while they compile in the background (a fresh install's first run does not wait); the long
    # ones compile them first (announced). $IPROMP_PIN_KERNELS overrides.
    from ..promp.compiled import BACKEND_ENV, set_announcer, set_kernel_backend

    short = args.command in ("run", "preview", "train", "synth")
    previous = set_kernel_backend(os.environ.get(BACKEND_ENV) or ("auto" if short else "numba"))
    set_announcer(lambda message: print(message, file=sys.stderr, flush=True))
    from .human_fit import HumanModelMisfit

    try:
        return int(args.func(args) or 0)
    except (HumanModelMisfit, UnreachableError) as exc:  # --strict-human, an arm that cannot reach:
        # refused like a plan that fails its checks
        print_error(args.command, str(exc))
        return EXIT_CHECKS_FAILED
    except IPrompPinError as exc:
        print_error(args.command, str(exc))
        return EXIT_ERROR
    except OSError as exc:  # a file the checks could not foresee (a full disk, a vanished folder)
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print_error(args.command, f"{where}{exc.strerror or exc}")
        return EXIT_ERROR
    finally:
        set_kernel_backend(previous)
        set_announcer(None)


def console_main() -> None:
    """The ``ipromp-pin`` console script: :func:`main`, its exit status the process's."""
    try:
        code = main()
    except KeyboardInterrupt:  # in the instant before main's handlers are in place
        code = EXIT_INTERRUPTED
    ignore_late_signals()  # the command has ended: a signal now would only hide its status
    sys.exit(code)
