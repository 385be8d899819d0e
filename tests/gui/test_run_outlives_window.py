"""A protocol run outlives its window: SIGKILL the GUI process mid-run (real processes, simulated rig).

The GUI (tests/gui/gui_child.py: the run panel on a run service) starts a TLRE at speed 10; once the
tangential stage is sliding, the test SIGKILLs the GUI process. The run service (its own process, own
session) must finish the run: the file is closed with status ``completed`` (default policy: the run
goes on) or ``aborted`` (``--orphan abort``: safe state once no client is connected), and the normal
load is released (the last recorded Fn is ~0). The service then stops by itself (idle, no client).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rigctl.runservice.client import spawn_service
from rigctl.runservice.server import service_alive
from rigctl.runservice.wire import Address
from rigctl.storage.reader import RunReader

ROOT = Path(__file__).resolve().parents[2]
RELEASED_N = 5.0


def _env() -> dict[str, str]:
    return dict(os.environ, QT_QPA_PLATFORM="offscreen",
                PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))


def _wait(pred, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:.0f} s waiting for {what}")
        time.sleep(0.1)


def _kill_gui_mid_run(tmp_path: Path, orphan: list[str]) -> tuple[Path, subprocess.Popen]:
    runtime = Path(f"/tmp/rigctl-test-{os.getpid()}-{tmp_path.name[-12:]}")  # short: socket path limit
    address = Address(runtime)
    service = spawn_service(address, "sim", "10", extra=["--idle-exit-s", "2", *orphan])
    _wait(lambda: service_alive(address), 90, "the run service to listen")
    out = tmp_path / "killed_gui.h5"
    gui = subprocess.Popen([sys.executable, str(ROOT / "tests/gui/gui_child.py"), str(runtime), str(out)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=_env(),
                           cwd=ROOT)
    seen = []
    try:
        assert gui.stdout is not None
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            line = gui.stdout.readline()
            if not line:
                break
            seen.append(line.strip())
            if "slide" in line:
                break
        assert any("slide" in s for s in seen), f"the GUI never reached the sliding step: {seen}"
        time.sleep(1.5)  # sliding, loaded
        assert gui.poll() is None
        gui.send_signal(signal.SIGKILL)
        gui.wait(10)
        assert gui.returncode == -signal.SIGKILL
        assert service.poll() is None, "the run service died with the GUI"
    finally:
        if gui.poll() is None:
            gui.kill()
    return out, service


def _released_and_closed(out: Path) -> tuple[str, list[str], float]:
    with RunReader(out) as r:
        status = r.status
        events = [e.name for e in r.events()]
        daq = r.read_daq()
    fn_end = float(abs(daq["fn_N"][-100:]).max())
    return status, events, fn_end


@pytest.fixture(autouse=True)
def _clean_runtime_dirs():
    yield
    for d in Path("/tmp").glob(f"rigctl-test-{os.getpid()}-*"):
        shutil.rmtree(d, ignore_errors=True)


@pytest.mark.slow
def test_sigkill_of_the_gui_mid_run_the_run_completes_and_the_load_is_released(tmp_path):
    out, service = _kill_gui_mid_run(tmp_path, [])
    service.wait(240)  # finishes the run, then stops: idle with no client
    assert service.returncode == 0
    status, events, fn_end = _released_and_closed(out)
    assert status == "completed", (status, events)
    assert "end" in events
    assert fn_end < RELEASED_N, f"normal load still on at the end of the file: {fn_end:.1f} N"


@pytest.mark.slow
def test_sigkill_of_the_gui_mid_run_with_orphan_abort_ends_aborted_in_the_safe_state(tmp_path):
    out, service = _kill_gui_mid_run(tmp_path, ["--orphan", "abort", "--orphan-grace-s", "1"])
    service.wait(120)
    assert service.returncode == 0
    status, events, fn_end = _released_and_closed(out)
    assert status == "aborted", (status, events)
    assert "safe_state" in events and "end" not in events
    assert fn_end < RELEASED_N, f"normal load still on after the safe state: {fn_end:.1f} N"
