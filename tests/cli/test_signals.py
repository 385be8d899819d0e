"""Every signal that ends `rigctl run` goes through the safe state; a stdout that has gone is
refused before motion and never loses a run's report (issue 35, items 2 and 7).

The handlers are tested in this process on a stand-in runner (fast); the real command line in a
subprocess on the simulated rig, signalled while loaded, the way a closed terminal or a dropped SSH
session (SIGHUP), Ctrl-\\ (SIGQUIT) or a scheduler (SIGTERM) ends it.
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from experiments.context import Controls
from rigctl.cli import streams
from rigctl.cli.run_signals import ENDING_SIGNALS, RunSignals, StoppedBeforeRun
from rigctl.runservice.client import spawn_service
from rigctl.runservice.server import service_alive
from rigctl.runservice.wire import Address
from rigctl.storage.reader import RunReader
from tests.cli.test_run_cli import RIGCTL, SHORT, entry_text, started, wait_for_samples

HANDLED = (*ENDING_SIGNALS, signal.SIGUSR1, signal.SIGUSR2)
RUN = ["run", "tlre", "--speed", "max", "--no-camera"]


@pytest.fixture
def handlers():
    """RunSignals installs process-wide handlers: put this process's own back afterwards."""
    saved = {s: signal.getsignal(s) for s in HANDLED}
    yield
    for s, h in saved.items():
        signal.signal(s, h)


class _Stage:
    def __init__(self) -> None:
        self.stopped = False

    def emergency_stop(self) -> None:
        self.stopped = True


def _runner() -> SimpleNamespace:
    return SimpleNamespace(controls=Controls(), devices=SimpleNamespace(
        tangential_stage=_Stage(), normal_stage=_Stage()))


@pytest.mark.parametrize("signum", list(ENDING_SIGNALS))
def test_every_ending_signal_is_handled_before_and_during_the_run(handlers, signum):
    sig = RunSignals()
    assert signal.getsignal(signum) == sig._on_ending  # none keeps its default (death)
    with pytest.raises(StoppedBeforeRun) as stopped:  # the rig starting: nothing moved yet
        signal.raise_signal(signum)
    assert stopped.value.exit_code == 128 + signum and "nothing moved" in str(stopped.value)
    runner = _runner()
    sig.attach(runner)
    signal.raise_signal(signum)
    assert runner.controls.aborted and runner.controls.abort_reason == ENDING_SIGNALS[signum]
    assert sig.exit_code == 128 + signum
    assert not runner.devices.normal_stage.stopped  # the first: the safe state, not an e-stop


def test_a_second_signal_is_the_emergency_stop_and_after_the_run_none_acts(handlers):
    sig = RunSignals()
    runner = _runner()
    sig.attach(runner)
    signal.raise_signal(signal.SIGHUP)
    signal.raise_signal(signal.SIGTERM)
    assert runner.devices.tangential_stage.stopped and runner.devices.normal_stage.stopped
    assert "SIGHUP" in runner.controls.abort_reason and sig.exit_code == 129  # the first counts
    sig.run_over()
    signal.raise_signal(signal.SIGINT)  # the run is over: neither raised nor the code changed
    assert sig.exit_code == 129


def test_a_hung_up_terminal_does_not_stop_the_abort(handlers, monkeypatch):
    """After SIGHUP stderr is a dead terminal (EIO): the message is dropped, the abort is not."""
    class Dead(io.StringIO):
        def write(self, s: str) -> int:
            raise OSError(5, "Input/output error")

    monkeypatch.setattr("sys.stderr", Dead())
    sig = RunSignals()
    runner = _runner()
    sig.attach(runner)
    signal.raise_signal(signal.SIGHUP)
    assert runner.controls.aborted


def test_the_report_goes_to_stderr_when_stdout_has_gone(monkeypatch, capsys):
    class Closed(io.StringIO):
        def write(self, s: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr("sys.stdout", Closed())
    streams.report(["completed: run.h5 (3.0 s wall)", "samples 3072, dropped 0"])
    err = capsys.readouterr().err
    assert "standard output is closed" in err
    assert "completed: run.h5 (3.0 s wall)\nsamples 3072, dropped 0\n" in err


# ----------------------------------------------------------------------------- the real command


LONG_SLIDE = [a if not a.startswith("travel_m=") else "travel_m=300e-6" for a in SHORT]
"""SHORT with a 30 s slide: loaded from about 18 s to 50 s of rig time (1.5 s wall at speed 20
after the signal is sent at 20 s: a loaded machine polling the file late still signals mid-run)."""


def _signalled_mid_run(tmp_path, signum: int) -> tuple[subprocess.Popen[str], str, object]:
    out = tmp_path / f"sig{signum}.h5"
    with started("run", "tlre", "--speed", "20", "--no-camera", "--out", str(out),
                 *LONG_SLIDE) as proc:
        wait_for_samples(out, 20 * 1024, proc)  # about 20 s of rig time: loaded (300 N), sliding
        proc.send_signal(signum)
        _, stderr = proc.communicate(timeout=60)
    return proc, stderr, out


@pytest.mark.parametrize("signum", [
    signal.SIGHUP, signal.SIGQUIT,
    pytest.param(signal.SIGTERM, marks=pytest.mark.slow),  # as SIGHUP; SIGINT: test_run_cli.py
])
@pytest.mark.slow
def test_a_signal_mid_run_releases_the_load_and_closes_the_file_aborted(tmp_path, signum):
    proc, stderr, out = _signalled_mid_run(tmp_path, signum)
    assert proc.returncode == 128 + signum, stderr
    assert "bringing the rig to a safe state" in stderr
    assert entry_text(out, "status") == "aborted"  # not 'running'
    assert signal.Signals(signum).name in entry_text(out, "error")
    with RunReader(out) as r:
        d = r.read_daq()
        names = [e.name for e in r.events()]
    assert "safe_state" in names
    assert d["fn_N"].max() > 250.0  # it had been loaded
    assert abs(d["fn_N"][-1]) < 1.0  # and the load was released before the file closed


@pytest.mark.slow
def test_a_run_whose_stdout_is_closed_before_the_plan_is_refused_before_motion(tmp_path):
    """`rigctl run tlre ... | true`: nobody saw the plan; nothing moves, one line, exit 2."""
    out = tmp_path / "never.h5"
    proc = subprocess.Popen([*RIGCTL, *RUN, "--out", str(out), *SHORT], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader goes away at once, as `| true` does
    stderr = proc.stderr.read()
    assert proc.wait(timeout=120) == 2, stderr
    assert stderr.startswith("rigctl: error: standard output is closed") and stderr.count("\n") == 1
    assert "nothing moved" in stderr
    assert not out.exists()


@pytest.mark.slow
def test_a_run_whose_stdout_closes_after_the_plan_completes_and_reports_on_stderr(tmp_path):
    """The reader saw the plan and went away: the rig moves, the run completes and is recorded,
    and the report the closed stdout cannot take goes to stderr; the exit code is the run's."""
    out = tmp_path / "reader_gone.h5"
    with started(*RUN, "--out", str(out), *SHORT) as proc:
        assert proc.stdout is not None
        seen = []
        while not (seen and seen[-1].startswith("run file:")):
            line = proc.stdout.readline()
            assert line, (seen, proc.stderr.read() if proc.stderr else "")
            seen.append(line)
        proc.stdout.close()
        stderr = proc.stderr.read() if proc.stderr else ""
        assert proc.wait(timeout=120) == 0, stderr
    assert "standard output is closed" in stderr and f"completed: {out}" in stderr
    assert entry_text(out, "status") == "completed"


@pytest.mark.slow
def test_the_run_service_outlives_a_hang_up_and_stops_safely_on_sigquit():
    """The service runs protocols too: a closed terminal (SIGHUP) never ends it; SIGQUIT goes the
    way of SIGTERM (abort any run to the safe state, stop), not its default core dump."""
    address = Address(Path(f"/tmp/rigctl-sig-{os.getpid()}"))
    proc = spawn_service(address, "sim", "max", extra=["--idle-exit-s", "60"])
    try:
        deadline = time.monotonic() + 90
        while not service_alive(address):
            assert time.monotonic() < deadline and proc.poll() is None, "service did not start"
            time.sleep(0.1)
        proc.send_signal(signal.SIGHUP)
        time.sleep(0.5)
        assert proc.poll() is None, "the run service died of SIGHUP"
        proc.send_signal(signal.SIGQUIT)
        assert proc.wait(30) == 0
        assert not Path(address.socket).exists()  # stopped its own way: the socket removed
    finally:
        if proc.poll() is None:
            proc.kill()
        shutil.rmtree(address.directory, ignore_errors=True)
