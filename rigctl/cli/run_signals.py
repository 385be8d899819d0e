"""Signals during `rigctl run`: every signal that ends the process goes through the safe state.

Ctrl-C (SIGINT), SIGTERM, SIGHUP (the terminal closed, the SSH session dropped) and SIGQUIT
(Ctrl-\\) are handled alike, from before the rig opens to the end of the run:

* before the run exists (the rig starting, the plan being made): nothing has moved; the command
  stops there with one line and exit code 128 + the signal (:class:`StoppedBeforeRun`);
* during the run: the run is aborted (the runner stops the tangential stage, releases the normal
  load, closes the run file ``aborted`` with the signal named); a second such signal escalates to
  the emergency stop of both stages (the run file is still closed with its status); the exit code
  is 128 + the first signal;
* after the run: the rig is already in its safe state; the signal is ignored so that the run's
  report and exit code are not lost.

SIGUSR1 pauses and SIGUSR2 resumes, also when asked while the rig starts (kept, applied at the
start). What a handler says goes to stderr and may fail (a hung-up terminal): the abort is asked
first, and a message that cannot be written is dropped, never raised into the run.
"""

from __future__ import annotations

import contextlib
import signal
from types import FrameType
from typing import TYPE_CHECKING

from rigctl.cli.streams import say

if TYPE_CHECKING:
    from experiments.runner import Runner

ENDING_SIGNALS: dict[int, str] = {
    signal.SIGINT: "interrupted (Ctrl-C)",
    signal.SIGTERM: "terminated (SIGTERM)",
    signal.SIGHUP: "hung up (SIGHUP: the terminal or the SSH session closed)",
    signal.SIGQUIT: "quit (SIGQUIT)",
}
"""The signals whose default action ends the process, and how a run they end is recorded."""


class StoppedBeforeRun(KeyboardInterrupt):
    """An ending signal before the run started: nothing moved; exit code 128 + the signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"{ENDING_SIGNALS[signum]} before the run started: nothing moved")
        self.exit_code = 128 + signum


class RunSignals:
    """The run command's signal handlers, installed before anything opens or moves."""

    def __init__(self) -> None:
        self.paused = False
        self.first_signum: int | None = None
        self._count = 0
        self._runner: Runner | None = None
        self._over = False
        self.quiet_pause = False
        for signum in ENDING_SIGNALS:
            signal.signal(signum, self._on_ending)
        signal.signal(signal.SIGUSR1, self._on_pause)
        signal.signal(signal.SIGUSR2, self._on_resume)

    @property
    def exit_code(self) -> int:
        """128 + the first ending signal (130 if none: an abort from elsewhere)."""
        return 128 + (self.first_signum if self.first_signum is not None else signal.SIGINT)

    def attach(self, runner: Runner, quiet_pause: bool = False) -> None:
        """From now on signals act on ``runner``; a pause asked earlier is applied. With
        ``quiet_pause`` the pause/resume messages are left to the progress bar."""
        self.quiet_pause = quiet_pause
        self._runner = runner
        if self.paused:
            runner.controls.pause()

    def run_over(self) -> None:
        """The run has ended (the rig is in its safe state): ending signals are ignored from now."""
        self._over = True

    def _on_ending(self, signum: int, frame: FrameType | None) -> None:
        if self._over:
            return
        runner = self._runner
        if runner is None:
            raise StoppedBeforeRun(signum)
        self._count += 1
        if self._count == 1:
            self.first_signum = signum
            runner.controls.abort(ENDING_SIGNALS.get(signum, f"signal {signum}"))
            say(f"\n{ENDING_SIGNALS.get(signum, f'signal {signum}')}: bringing the rig to a safe "
                "state (Ctrl-C again: emergency stop)")
            return
        for stage in (runner.devices.tangential_stage, runner.devices.normal_stage):
            with contextlib.suppress(Exception):
                stage.emergency_stop()
        runner.controls.abort(f"{ENDING_SIGNALS.get(signum, f'signal {signum}')} twice: "
                              "emergency stop")
        say("\nsecond interrupt: EMERGENCY STOP of both stages; the run file is closed with its "
            "status (a load the stop leaves on is reported)")

    def _on_pause(self, signum: int, frame: FrameType | None) -> None:
        self.paused = True
        if self._runner is None:
            say("pause asked while the rig starts: the run will start paused (SIGUSR2 resumes)")
            return
        self._runner.controls.pause()
        if not self.quiet_pause:
            say("paused (SIGUSR1; SIGUSR2 resumes)")

    def _on_resume(self, signum: int, frame: FrameType | None) -> None:
        self.paused = False
        if self._runner is None:
            say("resume asked while the rig starts")
            return
        self._runner.controls.resume()
        if not self.quiet_pause:
            say("resumed (SIGUSR2)")
