"""What a running procedure works with: devices, acquisition, limits, and the operator's controls.

The experiment clock is the DAQ's device time: holds and timeouts are measured on it, so a procedure
behaves the same on the real rig and on an accelerated simulated rig. "Now" is the device time of the
present instant (``acq.device_now_s()``), which a paced simulated rig runs ahead of the newest
recorded sample (``acq.t_s``); waits end when the recorded data reach the time waited for.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from drivers.interfaces import LoadingStage, StageLimits
from drivers.safety import ForceGuard
from experiments.errors import ProcedureError, ProtocolAborted
from rigctl.acquisition import Acquisition, RigDevices

TANGENTIAL = "tangential"
"""Device name of the tangential stage (as the drivers name it in their errors)."""
NORMAL = "normal"
"""Device name of the normal stage."""


@dataclass(frozen=True)
class RigLimits:
    """The limits a plan is checked against before anything moves.

    Each axis's limits are the :class:`~drivers.interfaces.StageLimits` its driver checks every move
    against; the dry run calls the same checks (:func:`experiments.steps.within_limits`).
    """

    tangential: StageLimits
    normal: StageLimits
    max_force_N: float
    contact_search_end_m: float = math.inf
    """Furthest the contact search may go without reading a contact (the expected contact)."""
    max_approach_m: float = math.inf
    """Furthest the normal stage may press past where it first read a contact."""
    force_range_N: float = math.inf
    """The force sensor's range (:attr:`drivers.interfaces.Daq.force_range_N`): a reading there is
    saturated, so no force target may be above it. A :class:`~experiments.runner.Runner` lowers it
    to its DAQ's own range."""


class Controls:
    """Pause, resume and abort, usable from any thread (GUI, signal handler, tests)."""

    def __init__(self) -> None:
        self._pause = threading.Event()
        self._abort = threading.Event()
        self.abort_reason = ""

    def pause(self) -> None:
        self._pause.set()

    def resume(self) -> None:
        self._pause.clear()

    def abort(self, reason: str = "aborted by the operator") -> None:
        if not self._abort.is_set():
            self.abort_reason = reason
        self._abort.set()

    @property
    def paused(self) -> bool:
        return self._pause.is_set()

    @property
    def aborted(self) -> bool:
        return self._abort.is_set()

    @property
    def abort_event(self) -> threading.Event:
        return self._abort


class RunContext:
    """Devices, acquisition, limits and controls of one running procedure."""

    poll_s = 0.01
    """Host interval of status polls while waiting (keeps reaction to faults and aborts < 0.1 s)."""

    def __init__(
        self,
        devices: RigDevices,
        acq: Acquisition,
        limits: RigLimits,
        controls: Controls,
        force_guard: ForceGuard | None = None,
    ) -> None:
        self.devices = devices
        self.acq = acq
        self.limits = limits
        self.controls = controls
        self.force_guard = force_guard
        self.z_retract_m: float | None = None
        """Normal-stage position before the first contact: where releasing the load goes back to."""
        self.z_contact_m: float | None = None
        """Normal-stage position where the load step first read a contact (the approach bound,
        :attr:`RigLimits.max_approach_m`, counts from it); None until then and after a release."""
        self.x_start_m: float | None = None
        """Tangential-stage position when the protocol started: where returns go back to."""
        self.current_step = ""

    @property
    def tangential(self) -> LoadingStage:
        return self.devices.tangential_stage

    @property
    def normal(self) -> LoadingStage:
        return self.devices.normal_stage

    def checkpoint(self) -> None:
        """Raise a device error seen by the acquisition, or ProtocolAborted."""
        self.acq.check()
        if self.controls.aborted:
            raise ProtocolAborted(self.controls.abort_reason)

    def sleep(self) -> None:
        """One poll interval (host time), then a checkpoint."""
        self.acq.faulted.wait(self.poll_s)
        self.checkpoint()

    def now_s(self) -> float:
        """Device time of the present instant [s] (``Acquisition.device_now_s``: on a paced simulated
        rig ahead of the newest recorded sample); waits for the first DAQ block if needed.

        A wait from here (:meth:`wait_device_time`) ends when the recorded data have caught up with
        it, so a reading after a move is of data from after the move, however far behind the
        recorder is."""
        deadline = time.monotonic() + 5.0
        while math.isnan(self.acq.t_s):  # NaN before the first block
            self.checkpoint()
            if time.monotonic() > deadline:
                raise ProcedureError("no DAQ data within 5 s of the start")
            time.sleep(self.poll_s)
        return self.acq.device_now_s()

    def wait_device_time(self, t_end_s: float, host_timeout_s: float) -> None:
        """Wait until device time reaches ``t_end_s`` (checkpoints meanwhile)."""
        deadline = time.monotonic() + host_timeout_s
        while not self.acq.wait_until(t_end_s, self.poll_s * 5, self.controls.abort_event):
            self.checkpoint()
            if time.monotonic() > deadline:
                raise ProcedureError(
                    f"{self.current_step}: device time did not reach {t_end_s:.3f} s "
                    f"(at {self.acq.t_s:.3f} s) within {host_timeout_s:.0f} s"
                )
        self.checkpoint()

    def fn_N(self, average_s: float = 0.05) -> float:
        """Normal force averaged over the last ``average_s`` of device time."""
        return self.acq.mean("fn_N", average_s)
