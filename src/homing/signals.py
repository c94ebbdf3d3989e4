"""SIGTERM and SIGHUP stop a command exactly as Ctrl-C does.

Ctrl-C raises :class:`KeyboardInterrupt` in the main thread, and the code
that owns a robot (the runner) turns it into a clean stop: zero command,
tree halted, services shut down, the summary printed, the map and logs
written. A service manager's SIGTERM, or the SIGHUP of a closed terminal,
must not lose any of that, so :func:`stop_on_signals` makes the three
signals raise the same exception (:class:`Interrupted`, a
``KeyboardInterrupt`` that knows its signal). :func:`received` tells what
stopped the run; the exit status is ``128 + signal number``, as a shell
reports a process killed by it (130 for Ctrl-C, 143 for SIGTERM).

A second signal while the first is being handled raises again: pressing
Ctrl-C twice still forces the way out.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_received: list[int] = []
_active: list[bool] = []  # one entry per open stop_on_signals block


class Interrupted(KeyboardInterrupt):
    """A stop asked by signal ``signum`` (a ``KeyboardInterrupt``: whatever handles Ctrl-C handles it)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _handler(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise Interrupted(signum)


def received() -> int | None:
    """The first stop signal received inside :func:`stop_on_signals`, or None."""
    return _received[0] if _received else None


def stop_requested() -> bool:
    """Whether a stop signal has arrived inside the open :func:`stop_on_signals` block.

    Loops poll this as well as catching :class:`Interrupted`: an exception raised
    by the handler can be swallowed by code it lands in (a library's clean-up, a
    callback from C), and a stop must never be lost.
    """
    return bool(_active) and bool(_received)


def signal_name(signum: int | None) -> str:
    """``"SIGTERM"`` for 15; ``"Ctrl-C"`` for SIGINT or None (a plain KeyboardInterrupt)."""
    if signum is None or signum == signal.SIGINT:
        return "Ctrl-C"
    return signal.Signals(signum).name


def exit_status(signum: int | None) -> int:
    """The shell's status for a process stopped by ``signum`` (SIGINT when None): 128 + its number."""
    return 128 + int(signum if signum is not None else signal.SIGINT)


@contextmanager
def stop_on_signals(signums: tuple[int, ...] = STOP_SIGNALS) -> Iterator[None]:
    """Within the block, each of ``signums`` raises :class:`Interrupted`; previous handlers come back after.

    A signal the process was started ignoring (``nohup`` ignores SIGHUP) stays
    ignored. Only the main thread can install handlers: elsewhere this does nothing.
    """
    previous: dict[int, object] = {}
    _received.clear()
    try:
        for s in signums:
            if signal.getsignal(s) is not signal.SIG_IGN:
                previous[s] = signal.signal(s, _handler)
    except ValueError:  # not the main thread
        pass
    _active.append(True)
    try:
        yield
    finally:
        _active.pop()
        for s, old in previous.items():
            signal.signal(s, old)  # type: ignore[arg-type]
