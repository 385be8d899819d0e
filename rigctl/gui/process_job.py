"""Long work (fits, analyses) in a worker process the window follows without ever waiting on it.

:class:`ProcessJob` starts ``target(report, *args)`` in a fresh ``spawn`` process (never a ``fork``
of the Qt process: a forked copy of a GUI with threads can deadlock). The target calls
``report(text, fraction)`` to tell its progress (``fraction`` in [0, 1], or NaN when unknown) and
returns a picklable result. A QTimer in the GUI thread polls the job's queue every
``POLL_INTERVAL_MS`` and emits Qt signals: ``progress``, then ``finished(result)`` or
``failed(message)``. :meth:`ProcessJob.cancel` stops the process (SIGTERM, so a diagnosis kills its
own candidate-fit workers on the way out, see :mod:`rigctl.workbench.interrupts`; SIGKILL after
``CANCEL_GRACE_S``) and emits ``cancelled``.

The worker asks the kernel to kill it when the window's process dies (Linux ``PR_SET_PDEATHSIG``),
so not even a killed window leaves a fit running; a window that quits normally cancels its jobs
(``QCoreApplication.aboutToQuit``). The process is not a daemon: a diagnosis starts processes of its
own, which a daemon may not.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import math
import multiprocessing
import os
import queue
import signal
import sys
import time
import traceback
from collections.abc import Callable
from multiprocessing.process import BaseProcess
from typing import Any

from PySide6.QtCore import QCoreApplication, QObject, QTimer, Signal

POLL_INTERVAL_MS = 100
CANCEL_GRACE_S = 3.0
Report = Callable[[str, float], None]
"""``report(text, fraction)``: the worker's progress (fraction in [0, 1] or NaN)."""

_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _die_with_parent(parent_pid: int) -> None:
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


def _child(target: Callable[..., Any], args: tuple[Any, ...], out: Any, parent_pid: int) -> None:
    """The worker process: run the target, put ``("progress", text, fraction)`` items while it
    works and one ``("result", value)`` or ``("error", message)`` at the end."""
    _die_with_parent(parent_pid)

    def report(text: str, fraction: float = math.nan) -> None:
        out.put(("progress", str(text), float(fraction)))

    try:
        result = target(report, *args)
    except BaseException as exc:  # every failure goes back to the window as text
        detail = traceback.format_exc(limit=6)
        out.put(("error", f"{type(exc).__name__}: {exc}", detail))
    else:
        out.put(("result", result))
    out.close()
    out.join_thread()


class ProcessJob(QObject):
    """One unit of work in a worker process; one job at a time per object."""

    progress = Signal(str, float)
    finished = Signal(object)
    failed = Signal(str)
    cancelled = Signal()

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._ctx = multiprocessing.get_context("spawn")
        self._proc: BaseProcess | None = None
        self._queue: Any = None
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_INTERVAL_MS)
        self._timer.timeout.connect(self._poll)
        self.name = ""
        self.started_at = math.nan
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(self.cancel)

    @property
    def running(self) -> bool:
        return self._proc is not None

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    def start(self, name: str, target: Callable[..., Any], *args: Any) -> None:
        """Start ``target(report, *args)`` (a module-level function; args picklable)."""
        if self._proc is not None:
            raise RuntimeError(f"a job is already running ({self.name})")
        self.name = name
        self._queue = self._ctx.Queue()
        self._proc = self._ctx.Process(target=_child, args=(target, args, self._queue, os.getpid()),
                                       name=f"rigctl-gui-{name}", daemon=False)
        self._proc.start()
        self.started_at = time.monotonic()
        self._timer.start()

    def cancel(self) -> bool:
        """Stop the running job (its result, if any, is dropped); False if none was running."""
        proc = self._proc
        if proc is None:
            return False
        self._end()
        if proc.is_alive():
            proc.terminate()
            proc.join(CANCEL_GRACE_S)
            if proc.is_alive():
                proc.kill()
                proc.join(CANCEL_GRACE_S)
        self.cancelled.emit()
        return True

    def _end(self) -> None:
        self._timer.stop()
        self._proc = None
        q, self._queue = self._queue, None
        if q is not None:
            with contextlib.suppress(Exception):
                q.cancel_join_thread()
                q.close()

    def _poll(self) -> None:
        q, proc = self._queue, self._proc
        if q is None or proc is None:
            return
        dead = not proc.is_alive()  # before draining: all it wrote is in the pipe by then
        while True:
            try:
                item = q.get_nowait()
            except queue.Empty:
                break
            except (EOFError, OSError):  # the worker died while writing
                item = ("error", "the worker process's output was cut off", "")
            kind = item[0]
            if kind == "progress":
                self.progress.emit(item[1], item[2])
                continue
            self._end()
            proc.join(CANCEL_GRACE_S)
            if kind == "result":
                self.finished.emit(item[1])
            else:
                self.failed.emit(item[1])
            return
        if dead:
            code = proc.exitcode
            self._end()
            self.failed.emit(f"the worker process ended without a result (exit code {code})")
