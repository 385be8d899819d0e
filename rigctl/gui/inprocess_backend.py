"""The run panel's in-process back-end: each dry run or run in a worker thread of the window.

The worker opens the rig (or uses the one the panel was given), builds the run with
:meth:`rigctl.rigs.OpenRig.runner` (as ``rigctl run`` does), plans and runs it, and talks to the GUI
only by emitting :class:`~rigctl.gui.run_backend.BackendSignals`. The GUI talks to the worker only
through :class:`~experiments.context.Controls` (thread-safe pause/resume/abort). A crash of the
window aborts the run (``--in-process``; tests and debugging).
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator
from typing import Any

from experiments.context import Controls
from experiments.errors import PlanError
from experiments.runner import Runner
from rigctl.acquisition import Acquisition
from rigctl.config import RigConfig
from rigctl.gui.run_backend import (
    FRAME_MAILBOX,
    SUBSCRIPTION_BLOCKS,
    BackendSignals,
    JobFrames,
    JobResult,
    RunJob,
)
from rigctl.rigs import OpenRig, open_rig
from rigctl.runservice.culprits import refusal_culprits
from rigctl.runservice.events import WarningForwarder
from rigctl.runservice.frames import start_forwarding

CAMERA_SUBSCRIPTION = 120
"""Bound of the subscription to the acquisition's camera frames (reduced before the GUI)."""


class InProcessBackend:
    """Jobs in a worker thread of this process, on ``rig`` (held by the caller) or on a rig of
    ``backend`` opened with ``config`` for each job and closed after it."""

    def __init__(self, signals: BackendSignals, config: RigConfig, backend: str,
                 rig: OpenRig | None = None) -> None:
        self._sig = signals
        self._config = config
        self._backend = backend
        self._given_rig = rig
        self._rig: OpenRig | None = rig
        """The rig of the latest job (closed again unless it was given)."""
        self._thread: threading.Thread | None = None
        self._controls = Controls()
        self._frames = JobFrames(FRAME_MAILBOX)

    @property
    def busy(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def has_service(self) -> bool:
        return False

    def new_job(self) -> int:
        return self._frames.new_job()

    def start(self, job: RunJob) -> bool:
        self._controls = Controls()
        self._thread = threading.Thread(target=self._work, args=(job, self._controls),
                                        name="rigctl-gui-run", daemon=False)
        self._thread.start()
        return True

    def enqueue(self, job: RunJob) -> bool:
        return False

    def adopt(self) -> None:
        """Never needed: nothing starts a job here but :meth:`start`."""

    def ended(self) -> None:
        self._thread = None

    def pause(self) -> None:
        self._controls.pause()

    def resume(self) -> None:
        self._controls.resume()

    def abort(self, reason: str) -> None:
        self._controls.abort(reason)
        self._controls.resume()

    def emergency_stop(self, reason: str) -> str:
        """The abort is set before the stages are stopped, so that the protocol's step sees an abort
        (status ``aborted``) rather than only the stage alarm the e-stop causes."""
        busy = self.busy
        if busy:
            self.abort(reason)
        rig = self._given_rig if self._given_rig is not None else (self._rig if busy else None)
        if rig is None:
            return "EMERGENCY STOP: no rig is open (nothing is moving)"
        failures = trigger_emergency_stop(rig, reason)
        return "EMERGENCY STOP: stages stopped, motion refused until reset" + (
            f"; failed: {failures}" if failures else "")

    def send(self, kind: str, payload: Any = None) -> bool:
        return False

    def drain_frames(self) -> list[Any]:
        return self._frames.drain()

    def wait(self, timeout_s: float) -> bool:
        if self._thread is not None:
            self._thread.join(timeout_s)
        return not self.busy

    def close(self) -> None:
        """Nothing held between jobs (a given rig is its owner's to close)."""

    # ------------------------------------------------------------------ worker thread
    @contextlib.contextmanager
    def _open(self, job: RunJob) -> Iterator[OpenRig]:
        if self._given_rig is not None:
            yield self._given_rig
            return
        with open_rig(self._backend, self._config, job.speed) as rig:
            self._rig = rig
            yield rig

    def _work(self, job: RunJob, controls: Controls) -> None:
        """Runs in the worker thread: talks to the GUI only by emitting signals."""
        result = JobResult("error", "nothing done")
        warnings = WarningForwarder(lambda level, text: self._sig.run_event.emit(level, text)).install()
        try:
            with self._open(job) as rig:
                runner = self._runner(job, rig, controls)
                try:
                    plan, _ = runner.plan()
                except PlanError as exc:
                    x0 = rig.devices.tangential_stage.position_m()
                    result = JobResult("refused", f"dry run refused: {exc}", culprits=refusal_culprits(
                        job.protocol, job.given, rig.limits, x0, str(exc)))
                    return
                self._sig.planned.emit(plan)
                if job.dry:
                    result = JobResult("dry", "dry run: nothing moved")
                    return
                outcome = runner.run()
                result = JobResult("run", outcome.status, outcome)
        except PlanError as exc:
            result = JobResult("refused", f"refused: {exc}")
        except Exception as exc:
            result = JobResult("error", f"{type(exc).__name__}: {exc}")
        finally:
            warnings.remove()
            self._sig.done.emit(result)

    def _runner(self, job: RunJob, rig: OpenRig, controls: Controls) -> Runner:
        sig = self._sig

        def on_acquisition(acq: Acquisition) -> None:
            sig.subscribed.emit(acq.publisher.subscribe("daq", maxlen=SUBSCRIPTION_BLOCKS))
            if acq.record_camera:
                worker = threading.current_thread()
                start_forwarding(acq.publisher.subscribe("camera", maxlen=CAMERA_SUBSCRIPTION),
                                 lambda frame: self._frames.put(job.serial, frame),
                                 worker.is_alive, name="rigctl-gui-frames")

        def progress(i: int, n: int, desc: str, elapsed: float, eta: float) -> None:
            ctx = runner.ctx
            sig.progress.emit(i, n, desc, elapsed, eta, ctx.acq.t_s if ctx else math.nan)

        runner = rig.runner(  # built as rigctl run builds it (rigctl/rigs.py)
            job.protocol, job.given, out=job.out, camera=job.camera, operator=job.operator,
            notes=job.notes, metadata={"started_from": "gui"}, controls=controls,
            progress=progress, overwrite=job.overwrite, on_acquisition=on_acquisition,
        )
        return runner


def trigger_emergency_stop(rig: OpenRig, reason: str) -> str:
    """Trigger the latched emergency stop of every registry the rig's stages are on; failures as text."""
    registries: list[Any] = []
    for stage in (rig.devices.tangential_stage, rig.devices.normal_stage):
        reg = stage.emergency_stop_registry
        if all(reg is not r for r in registries):
            registries.append(reg)
    failures = [f"{f.stage_name}: {f.error}" for reg in registries for f in reg.trigger(reason)]
    return "; ".join(failures)
