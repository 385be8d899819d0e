"""Ctrl-C and SIGTERM during a search: raised where the search waits, and never lost.

Within :func:`signals_raise` (the main thread only), SIGINT raises ``KeyboardInterrupt`` and
SIGTERM raises :class:`Terminated` (a ``KeyboardInterrupt`` whose exit code is 143) instead of
ending the process on the spot, so that the search's worker processes are terminated on the way
out. Each signal is also *noted*: Python runs a signal handler at the next bytecode of the main
thread, and when that bytecode belongs to a destructor run by the garbage collector (any object's
``__del__``, a library's temporary file), the exception is printed as "Exception ignored in ..."
and dropped. The search would then go on waiting for workers that ignore SIGINT (by design: Ctrl-C
reaches the whole process group, and the parent decides), and the command would never end.

So every place a search waits or checks its budget calls :func:`raise_if_signalled`, which raises
the noted signal again; and if the block ends normally with a signal noted, it raises there. The
dropped exception's traceback is not printed (``sys.unraisablehook`` for a destructor's
"Exception ignored ...", ``sys.excepthook`` for compiled code that prints what it cannot pass on):
it is raised again where it can act, and the command ends with its one line. (The destructor seen in
practice: scipy's Sobol sampler loads its direction numbers with ``numpy.load`` and leaves the
``NpzFile``, a reference cycle, to the cyclic garbage collector, which runs it at any bytecode.) Only
handlers at their defaults are replaced (``signal.default_int_handler`` for SIGINT, ``SIG_DFL`` for
SIGTERM): a handler someone else installed (``rigctl run``'s safe-state handlers, a test harness)
is left alone. Nested blocks share the outermost's handlers and notes; each block's end raises a
signal noted and not yet raised.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived while a search or its workers ran: exit code 143 (128 + 15)."""

    exit_code = 128 + signal.SIGTERM

    def __init__(self) -> None:
        super().__init__("terminated (SIGTERM)")


_noted: list[int] = []
"""The signals noted inside the outermost :func:`signals_raise` block, in order."""
_depth = 0
"""How many :func:`signals_raise` blocks the main thread is in."""


def _exception(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _note_and_raise(signum: int, frame: Any) -> None:
    _noted.append(signum)
    raise _exception(signum)


def _quiet_for_noted(previous: Any) -> Any:
    """An unraisable-exception hook that drops a noted signal's exception (it is raised again at
    the next check) and passes anything else to ``previous``."""

    def hook(unraisable: Any) -> None:
        if _noted and isinstance(unraisable.exc_value, KeyboardInterrupt):
            return
        previous(unraisable)

    return hook


def _quiet_excepthook(previous: Any) -> Any:
    """An exception hook that drops a noted signal's exception and passes anything else on.
    Compiled code that cannot pass an exception on (a Cython function such as scipy's Sobol
    initialisation) prints it through ``sys.excepthook`` (``PyErr_PrintEx``) and goes on; a
    signal's exception that leaves the block is raised past it, never printed here."""

    def hook(exc_type: type[BaseException], exc: BaseException, tb: Any) -> None:
        if _noted and issubclass(exc_type, KeyboardInterrupt):
            return
        previous(exc_type, exc, tb)

    return hook


def raise_if_signalled() -> None:
    """Raise the first signal noted in this block (a no-op outside one, or when none came)."""
    if _noted:
        raise _exception(_noted[0])


@contextlib.contextmanager
def signals_raise() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise and are noted (module docstring)."""
    global _depth
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _depth:
        _depth += 1
        try:
            yield
            raise_if_signalled()
        finally:
            _depth -= 1
        return
    replaced = {s: signal.getsignal(s) for s, default in
                ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL))
                if signal.getsignal(s) is default}
    for s in replaced:
        signal.signal(s, _note_and_raise)
    previous_hook, previous_excepthook = sys.unraisablehook, sys.excepthook
    sys.unraisablehook = _quiet_for_noted(previous_hook)
    sys.excepthook = _quiet_excepthook(previous_excepthook)
    _depth = 1
    try:
        yield
        raise_if_signalled()  # a signal whose exception was dropped on the way
    finally:
        _depth = 0
        _noted.clear()
        sys.unraisablehook, sys.excepthook = previous_hook, previous_excepthook
        for s, previous in replaced.items():
            signal.signal(s, previous)
