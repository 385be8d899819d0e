"""The run panel's run-service back-end: jobs run in the run service, the window is its client.

The service (:mod:`rigctl.runservice`) owns the rig and outlives the window. Its messages arrive in
the client's reader thread, which only emits :class:`~rigctl.gui.run_backend.BackendSignals`
(queued into the GUI thread) and fills bounded mailboxes of live DAQ blocks and camera frames that
the GUI drains like a publisher subscription.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from PySide6.QtWidgets import QApplication

from rigctl.gui.run_backend import (
    FRAME_MAILBOX,
    SUBSCRIPTION_BLOCKS,
    BackendSignals,
    JobFrames,
    JobResult,
    LiveMailbox,
    RunJob,
)
from rigctl.runservice.client import ServiceClient
from rigctl.runservice.wire import JobSpec

MessageHandler = Callable[[str, Any], None]
Connect = Callable[[MessageHandler], ServiceClient]
"""Connects to a run service, handing its messages to the handler (``ServiceClient.ensure``)."""


def job_spec(job: RunJob) -> JobSpec:
    """What the run service is asked to run for ``job``."""
    return JobSpec(job.protocol.name, dict(job.given), None if job.out is None else str(job.out),
                   overwrite=job.overwrite, camera=job.camera, dry=job.dry,
                   speed_text=job.speed_text, operator=job.operator, notes=job.notes)


class ServiceBackend:
    """Jobs sent to the run service that ``connect`` reaches (started if none is listening)."""

    def __init__(self, signals: BackendSignals, connect: Connect) -> None:
        self._sig = signals
        self._busy = False
        """Set and cleared in the GUI thread only (start, adopt, ended), in the order the panel
        handles the service's messages."""
        self._mailbox = LiveMailbox(SUBSCRIPTION_BLOCKS)
        self._frames = JobFrames(FRAME_MAILBOX)
        self._live_announced = False
        self._client = connect(self.on_message)

    @property
    def busy(self) -> bool:
        return self._busy

    @property
    def has_service(self) -> bool:
        return True

    def new_job(self) -> int:
        return self._frames.new_job(self._reset_live)

    def _reset_live(self) -> None:
        self._live_announced = False
        self._mailbox.drain()

    def start(self, job: RunJob) -> bool:
        self._busy = self._client.send("start", job_spec(job))
        return self._busy

    def enqueue(self, job: RunJob) -> bool:
        return self._client.send("queue_add", job_spec(job))

    def adopt(self) -> None:
        self._busy = True

    def ended(self) -> None:
        self._busy = False

    def pause(self) -> None:
        self._client.send("pause")

    def resume(self) -> None:
        self._client.send("resume")

    def abort(self, reason: str) -> None:
        self._client.send("abort", reason)

    def emergency_stop(self, reason: str) -> str:
        """The service triggers the e-stop of its rig's stages and aborts its run."""
        if self._client.send("estop", reason):
            return "EMERGENCY STOP sent to the run service"
        return "EMERGENCY STOP could not be sent: the run service is gone"

    def send(self, kind: str, payload: Any = None) -> bool:
        return self._client.send(kind, payload)

    def drain_frames(self) -> list[Any]:
        return self._frames.drain()

    def wait(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while self._busy and time.monotonic() < deadline:
            QApplication.processEvents()  # the outcome arrives as a queued signal
            time.sleep(0.02)
        return not self._busy

    def close(self) -> None:
        self._client.close()

    # ------------------------------------------------------------------ reader thread
    def on_message(self, kind: str, payload: Any) -> None:
        """Runs in the client's reader thread: only fills the mailboxes and emits signals."""
        if kind == "daq":
            self._mailbox.put(payload)
            if not self._live_announced:
                self._live_announced = True
                self._sig.subscribed.emit(self._mailbox)
        elif kind == "frame":
            self._frames.put_latest(payload)
        elif kind == "planned":
            self._sig.planned.emit(payload)
        elif kind == "progress":
            self._sig.progress.emit(*payload)
        elif kind == "done":
            self._sig.done.emit(JobResult(payload.kind, payload.message, payload.outcome,
                                          tuple(getattr(payload, "culprits", ()))))
        elif kind == "started":
            if getattr(payload, "queue_item", None) is not None:
                # a queued run: its live data follow in this thread, so the live mailboxes are
                # reset here, in message order (the service sends all of the previous run's
                # before its done); reset in the GUI thread, this run's first items would go too
                self.new_job()
            self._sig.remote_started.emit(payload)
        elif kind == "queue":
            self._sig.queue_state.emit(payload)
        elif kind in ("hello", "state"):
            if getattr(payload, "queue", None) is not None:
                self._sig.queue_state.emit(payload.queue)
        elif kind == "devices":
            self._sig.devices.emit(payload)
        elif kind == "jog_result":
            self._sig.jog_result.emit(*payload)
        elif kind == "log":
            self._sig.service_log.emit(*payload)
        elif kind == "lost":
            self._sig.service_lost.emit()
