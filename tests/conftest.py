"""Shared test hygiene: no test leaves its signal handlers to the tests after it.

A command run in-process (``rigctl.cli.main.main(["run", ...])``) installs the run's safe-state
handlers and, as a process that ends would, never removes them; the next test in the same worker
would then find SIGINT handled by a run long over. Each test gets back the handlers it started
with.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator

import pytest

_SIGNALS = tuple(getattr(signal, name) for name in
                 ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2")
                 if hasattr(signal, name))


@pytest.fixture(autouse=True)
def _signal_handlers_restored() -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {s: signal.getsignal(s) for s in _SIGNALS}
    yield
    for s, handler in before.items():
        if handler is not None and signal.getsignal(s) is not handler:
            signal.signal(s, handler)
