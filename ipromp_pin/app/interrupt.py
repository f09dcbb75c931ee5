"""Interruptions of a command: Ctrl-C (SIGINT) and SIGTERM end it with one line and exit status 130
or 143, never a traceback, and leave no temporary file.

:func:`interruptible` makes both signals raise an exception in the main thread (SIGINT:
``KeyboardInterrupt``, also when the shell started the process with SIGINT ignored, as a
non-interactive shell does for ``cmd &``; SIGTERM: :class:`Terminated`, a ``KeyboardInterrupt``),
so that every ``with`` block unwinds: a staged output set is discarded
(:class:`ipromp_pin.atomic.OutputSet`), a temporary file is deleted (:func:`ipromp_pin.atomic.replacing`),
and an interrupted commit puts the earlier files back. Python runs a signal handler between two
bytecodes: inside a compiled kernel the interruption takes effect when the kernel returns; inside a
callback that cannot raise it (a compiler's ctypes callback, which Python reports as ignored and
goes on), it is sent again and raised where the command's code runs next. Once the command has
ended, both signals are ignored while the interpreter shuts down (:func:`ignore_late_signals`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

EXIT_INTERRUPTED = 130
"""Exit status after SIGINT (Ctrl-C): 128 + 2."""

EXIT_TERMINATED = 143
"""Exit status after SIGTERM: 128 + 15."""


RESEND_DELAY_S = 0.005
"""Delay [s] after which an interruption that a callback could not raise is sent again (the hook that
sends it has returned by then)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived (raised in the main thread by :func:`interruptible`'s handler)."""


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise Terminated()


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Within the block, SIGINT raises ``KeyboardInterrupt`` and SIGTERM :class:`Terminated`; the
    previous handlers come back afterwards. Outside the main thread it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminate)
    hook = sys.unraisablehook
    sys.unraisablehook = _raise_again(hook)
    try:
        yield
    finally:
        sys.unraisablehook = hook
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)


def _raise_again(hook: Callable[[Any], object]) -> Callable[[Any], object]:
    """An ``unraisablehook`` that sends an interruption a callback could not raise (e.g. a compiler's
    ctypes callback: Python prints it as ignored and goes on) to this process again, so that it is
    raised where the command's own code runs next; every other unraisable goes to ``hook``."""

    def again(unraisable: Any) -> object:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            sig = signal.SIGTERM if isinstance(unraisable.exc_value, Terminated) else signal.SIGINT
            # from another thread, a moment later: sent now, its handler would run (and raise) in here
            timer = threading.Timer(RESEND_DELAY_S, os.kill, args=(os.getpid(), sig))
            timer.daemon = True
            timer.start()
            return None
        return hook(unraisable)

    return again


def interruption_behind(exc: BaseException) -> KeyboardInterrupt | None:
    """The interruption (SIGINT, SIGTERM) that ``exc`` was raised while handling, if any: a library
    that catches the signal's exception and raises its own (its ``__context__`` or ``__cause__``)."""
    seen: set[int] = set()
    node: BaseException | None = exc
    while node is not None and id(node) not in seen:
        if isinstance(node, KeyboardInterrupt):
            return node
        seen.add(id(node))
        node = node.__cause__ or node.__context__
    return None


def report_interruption(command: str, exc: KeyboardInterrupt) -> int:
    """Print the one line of an interrupted command; returns its exit status (130 or 143)."""
    name, status = (
        ("SIGTERM", EXIT_TERMINATED) if isinstance(exc, Terminated) else ("SIGINT", EXIT_INTERRUPTED)
    )
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    where = f"ipromp-pin {command}" if command else "ipromp-pin"
    print(f"{where}: interrupted ({name}): nothing half-written; earlier outputs kept", file=sys.stderr)
    return status


def ignore_late_signals() -> None:
    """Once the command has ended (its outputs complete, or left as they were), SIGINT and SIGTERM
    change nothing: ignored while the interpreter shuts down (which can take a second), so that the
    process ends with the command's own status instead of being killed by the signal without a word.
    Outside the main thread it does nothing."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _exit_at_once(signum: int, frame: FrameType | None) -> None:
    terminated = signum == signal.SIGTERM
    name = "SIGTERM" if terminated else "SIGINT"
    print(f"ipromp-pin: interrupted ({name}) while starting; nothing written", file=sys.stderr, flush=True)
    os._exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED)


def exit_quietly_while_starting() -> None:
    """When this process is the ``ipromp-pin`` console script (or ``python -m ipromp_pin.app``), make
    SIGINT and SIGTERM end it at once with one line while its modules are still being imported
    (nothing is written then); :func:`interruptible` takes over when the command runs. Imported as a
    library (tests, a script calling :func:`ipromp_pin.app.main`), it changes nothing."""
    argv0 = sys.argv[0] if sys.argv else ""
    if argv0 != "-m" and os.path.basename(argv0) not in ("ipromp-pin", "ipromp-pin.exe"):
        return
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _exit_at_once)
        signal.signal(signal.SIGTERM, _exit_at_once)
