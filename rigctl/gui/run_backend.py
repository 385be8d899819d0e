"""Where the run panel's dry runs and runs execute: one back-end protocol, two implementations.

:class:`RunBackend` is all the panel (:mod:`rigctl.gui.run_panel`) knows of it. The back-end tells
the panel what happens through :class:`BackendSignals` (Qt signals, emitted in any thread, delivered
as queued calls in the GUI thread); the panel calls the back-end from the GUI thread only.

* :class:`~rigctl.gui.service_backend.ServiceBackend`: a client of the run service
  (:mod:`rigctl.runservice`), which owns the rig, so a run outlives the window (``rigctl gui``).
* :class:`~rigctl.gui.inprocess_backend.InProcessBackend`: a worker thread of the window's own
  process per action (``--in-process``, a panel given an open rig in tests).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from PySide6.QtCore import QObject, Signal

from experiments.protocols import Protocol as RigProtocol
from experiments.runner import RunOutcome

SUBSCRIPTION_BLOCKS = 512
"""Bound of the live-data mailbox (DAQ blocks); the panel drains it about 30 times a second."""
FRAME_MAILBOX = 16
"""Bound of the live camera-image mailbox (LiveFrames, a few a second)."""


@dataclass(frozen=True)
class RunJob:
    """A dry run or run as the panel's form asks for it."""

    dry: bool
    protocol: RigProtocol[Any]
    given: dict[str, str]
    """Parameters changed from their defaults, as text (``--param``)."""
    speed: float
    speed_text: str
    out: Path | None
    overwrite: bool
    camera: bool
    operator: str
    notes: str
    serial: int = 0
    """The job's serial (:meth:`RunBackend.new_job`): its camera frames are shown only while it is
    the latest (a finished run's forwarder flushes its last frame after the next run began)."""


@dataclass(frozen=True)
class JobResult:
    kind: str
    """'dry' (plan shown), 'refused' (plan error), 'run' (outcome), 'error' (nothing recorded)."""
    message: str = ""
    outcome: RunOutcome | None = None
    culprits: tuple[str, ...] = ()
    """For 'refused': the edited parameters that cause the refusal (their rows are marked)."""


class BackendSignals(QObject):
    """Everything a back-end tells the panel (and the panel the other tabs); emitted in any thread,
    delivered in the GUI thread."""

    planned = Signal(object)  # Plan
    subscribed = Signal(object)  # LiveBlocks: the live DAQ blocks of the run
    progress = Signal(int, int, str, float, float, float)  # i, n, step, elapsed, eta, device t
    done = Signal(object)  # JobResult
    service_log = Signal(str, str)  # level, text (run service)
    devices = Signal(object)  # RigSnapshot from the run service
    jog_result = Signal(bool, str)
    service_lost = Signal()
    live_blocks = Signal(object)  # list of DAQ blocks just drained (GUI thread; the live view)
    live_frames = Signal(object)  # list of LiveFrames just drained (GUI thread; the live view)
    run_event = Signal(str, str)  # level ("info", "warning", "error"), text: the run's events
    run_started = Signal(object)  # Path of the run file: a run (not a dry run) is starting
    remote_started = Signal(object)  # JobSpec: the run service started a run (the queue's too)
    queue_state = Signal(object)  # QueueState from the run service


class LiveBlocks(Protocol):
    """A bounded mailbox of live DAQ blocks: a publisher's subscription or :class:`LiveMailbox`."""

    dropped: int

    def drain(self) -> list[Any]: ...


class LiveMailbox:
    """Live items (DAQ blocks, camera frames), bounded like a publisher subscription: the oldest
    are dropped (counted) when the GUI falls behind."""

    def __init__(self, maxlen: int) -> None:
        self._items: deque[Any] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self.dropped = 0

    def put(self, item: Any) -> None:
        with self._lock:
            if len(self._items) == self._items.maxlen:
                self.dropped += 1
            self._items.append(item)

    def drain(self) -> list[Any]:
        with self._lock:
            items = list(self._items)
            self._items.clear()
            return items


class JobFrames:
    """The camera frames of the latest job: a frame of an earlier job is dropped, not shown.

    A run's frame forwarder flushes its last frame after the run ended, when the next run may have
    begun; shown there it put the previous run's rig times into the new run's Isum plot."""

    def __init__(self, maxlen: int) -> None:
        self._box = LiveMailbox(maxlen)
        self._lock = threading.Lock()
        self.serial = 0

    def new_job(self, also: Callable[[], None] | None = None) -> int:
        """A new job: the frames kept are dropped, ``also`` runs under the same lock (no frame of
        the previous job is put in between); the new job's serial."""
        with self._lock:
            self.serial += 1
            self._box.drain()
            if also is not None:
                also()
            return self.serial

    def put(self, serial: int, frame: Any) -> None:
        """A frame of job ``serial``: kept only while that job is the latest."""
        with self._lock:
            if serial == self.serial:
                self._box.put(frame)

    def put_latest(self, frame: Any) -> None:
        """A frame of the latest job (its source resets with :meth:`new_job` in message order)."""
        self._box.put(frame)

    def drain(self) -> list[Any]:
        return self._box.drain()


class RunBackend(Protocol):
    """Where the panel's jobs execute. Called from the GUI thread; answers with BackendSignals."""

    @property
    def busy(self) -> bool:
        """A job is going (from its start until the panel has handled its end: :meth:`ended`)."""
        ...

    @property
    def has_service(self) -> bool:
        """Runs go to the run service: the queue, jogs and the Devices tab go there too."""
        ...

    def new_job(self) -> int:
        """A new job begins: live data of earlier jobs are dropped; the new job's serial."""
        ...

    def start(self, job: RunJob) -> bool:
        """Start ``job`` (dry run or run); False if it could not be handed over (service gone)."""
        ...

    def enqueue(self, job: RunJob) -> bool:
        """Add ``job`` to the run service's queue; False without one or if it is gone."""
        ...

    def adopt(self) -> None:
        """A run the back-end started by itself (the service's queue) is now the panel's job."""
        ...

    def ended(self) -> None:
        """The panel has handled the job's end (its result, or the service lost)."""
        ...

    def pause(self) -> None: ...

    def resume(self) -> None: ...

    def abort(self, reason: str) -> None:
        """Abort the job: safe state (tangential stage stopped, normal load released), file
        closed ``aborted``."""
        ...

    def emergency_stop(self, reason: str) -> str:
        """The drivers' latched emergency stop of both stages (aborting a job); what was done."""
        ...

    def send(self, kind: str, payload: Any = None) -> bool:
        """A command to the run service (jog, reset_estop, queue_*); False without one."""
        ...

    def drain_frames(self) -> list[Any]:
        """The latest job's camera frames received since the last call."""
        ...

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the job to end; True if none is going."""
        ...

    def close(self) -> None:
        """Let go of the back-end (the run service stops by itself once idle with no client)."""
        ...
