"""What every simulated device server shares: its threads' start and stop, and use as a context manager.

A subclass says what to open before its threads start (:meth:`SimService._open`: a pty, a CAN bus),
which loops to run (:meth:`SimService._loops`, each checking :attr:`SimService.running` at least every
0.05 s), how to wake them for a stop (:meth:`SimService._wake`) and what to release once they have
ended (:meth:`SimService._close`)::

    class Echo(SimService):
        def _loops(self):
            return [(self._serve, "echo")]

        def _serve(self):
            while self.running:
                ...

    with Echo("echo") as server:   # start(); close() (stop()) on leaving, whatever happens
        ...
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import Self

JOIN_TIMEOUT_S = 5.0
"""How long stop() waits for each thread: loops look at ``running`` every <= 0.05 s, so 5 s is a hang."""


class SimService:
    """Base of the simulated servers (Modbus stage, CAN DAQ, serial probe) and the virtual rig's clock."""

    def __init__(self, name: str) -> None:
        self.service_name = name
        self._threads: list[threading.Thread] = []
        self._stop_event = threading.Event()
        self._started = False

    @property
    def running(self) -> bool:
        """True from :meth:`start` until :meth:`stop` is asked for."""
        return self._started and not self._stop_event.is_set()

    def start(self) -> Self:
        """Open, then start the loops; a second call does nothing."""
        if self._started:
            return self
        self._stop_event.clear()
        self._open()
        self._started = True
        for target, name in self._loops():
            thread = threading.Thread(target=target, name=f"{self.service_name}-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        """Ask the loops to end, wait for them, release what :meth:`_open` took; idempotent."""
        if not self._started:
            return
        self._stop_event.set()
        self._wake()
        for thread in self._threads:
            thread.join(timeout=JOIN_TIMEOUT_S)
        self._threads = []
        self._started = False
        self._close()

    def close(self) -> None:
        """End of use: :meth:`stop` (a subclass may also refuse a later start)."""
        self.stop()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # hooks ------------------------------------------------------------------------------------
    def _open(self) -> None:
        """Take what the loops need (called by :meth:`start` before any thread starts)."""

    def _loops(self) -> Sequence[tuple[Callable[[], None], str]]:
        """The thread targets and their names."""
        return ()

    def _wake(self) -> None:
        """Wake loops that wait on something else than :attr:`running` (called by :meth:`stop`)."""

    def _close(self) -> None:
        """Release what :meth:`_open` took (called by :meth:`stop` after the threads ended)."""
