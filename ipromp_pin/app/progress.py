"""What the command line writes to the terminal besides the commands' results: the progress line,
the one-line error message, and the exit statuses."""

from __future__ import annotations

import sys
import time

EXIT_ERROR = 2
"""Exit status of a user error (bad input, unwritable output): one line on standard error."""

EXIT_CHECKS_FAILED = 3
"""Exit status of ``run`` when the planned motion fails a required check or its timing verification."""


class ProgressLine:
    """Progress ``[done/total] label  elapsed`` rewritten in place on standard error, on a terminal
    only (to a file or a pipe it would be a stream of carriage returns). :meth:`end` finishes an
    unfinished line, so that an error message starts on a line of its own."""

    open_line = False

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()

    def __call__(self, done: int, total: int, label: str) -> None:
        if not self.tty:
            return
        stream = sys.stderr
        stream.write(f"\r[{done}/{total}] {label}  ({time.perf_counter() - self.t0:.0f} s)\033[K")
        ProgressLine.open_line = done != total
        if done == total:
            stream.write("\n")
        stream.flush()

    @staticmethod
    def end() -> None:
        if ProgressLine.open_line:
            sys.stderr.write("\n")
            sys.stderr.flush()
            ProgressLine.open_line = False


def progress() -> ProgressLine:
    """A progress callable (see :class:`ProgressLine`)."""
    return ProgressLine()


def print_error(command: str, message: str) -> None:
    """Print ``message`` as one line, starting on a line of its own (after an unfinished progress line)."""
    ProgressLine.end()
    text = " ".join(message.split("\n"))
    print(f"ipromp-pin {command}: error: {text}", file=sys.stderr)
