"""What the command line writes to the terminal besides the commands' results: the progress line,
the one-line error message, and the exit statuses."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

EXIT_ERROR = 2
"""Exit status of a user error (bad input, unwritable output): one line on standard error."""

EXIT_CHECKS_FAILED = 3
"""Exit status of ``run`` when the planned motion fails a required check or its timing verification."""


class ProgressLine:
    """Progress ``[done/total] label  (elapsed)`` on standard error.

    On a terminal one line rewritten in place. Elsewhere (a log file, ``nohup``, a SLURM job: carriage
    returns would be one endless line) a plain line at the first and the last step, every ``every``
    steps (default: a tenth of the total) and at least every ``interval_s`` seconds of steps, so a log
    shows that a long run goes on. :meth:`end` finishes an unfinished terminal line, so that an error
    message starts on a line of its own.
    """

    open_line = False

    def __init__(
        self,
        *,
        tty: bool | None = None,
        every: int | None = None,
        interval_s: float = 10.0,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.clock = clock
        self.t0 = clock()
        self.tty = sys.stderr.isatty() if tty is None else tty
        self.every = every
        self.interval_s = interval_s
        self.last_done = 0
        self.last_t = self.t0

    def __call__(self, done: int, total: int, label: str) -> None:
        stream = sys.stderr
        now = self.clock()
        text = f"[{done}/{total}] {label}  ({now - self.t0:.0f} s)"
        if not self.tty:
            step = self.every if self.every is not None else max(1, total // 10)
            due = done - self.last_done >= step or now - self.last_t >= self.interval_s
            if done in (1, total) or due:
                stream.write(text + "\n")
                stream.flush()
                self.last_done, self.last_t = done, now
            return
        stream.write(f"\r{text}\033[K")
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
