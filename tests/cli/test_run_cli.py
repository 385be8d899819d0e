"""`rigctl run` as a process: dry run, bad output paths, Ctrl-C, SIGKILL and a full disk.

These start the real command line in a subprocess (the simulated rig in the same process), the way
an operator or a scheduler does, and look at the run file it leaves.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.storage.reader import RunReader

RIGCTL = [sys.executable, "-m", "rigctl.cli.main"]
SHORT = ["--param", "repetitions=1", "--param", "travel_m=100e-6", "--param", "velocity_m_s=1e-5",
         "--param", "settle_s=1", "--param", "preload_hold_s=1"]


def rigctl(*args: str, timeout: float = 120.0, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*RIGCTL, *args], capture_output=True, text=True, timeout=timeout, **kw)


def start(*args: str, **kw) -> subprocess.Popen[str]:
    return subprocess.Popen([*RIGCTL, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


@contextlib.contextmanager
def started(*args: str, **kw) -> Iterator[subprocess.Popen[str]]:
    """:func:`start`, killed on leaving the block if it is still running (a failed assertion
    must not leave a rig process behind)."""
    proc = start(*args, **kw)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()


def wait_for_samples(path: Path, n: int, proc: subprocess.Popen[str], timeout_s: float = 60.0) -> int:
    """Follow the run file while it is written (SWMR) until it holds ``n`` samples."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        if path.exists():
            try:
                with RunReader(path) as r:
                    if r.n_samples >= n:
                        return r.n_samples
            except Exception:  # the file is being created: not yet a complete layout
                pass
        time.sleep(0.1)
    raise AssertionError(f"{path} never reached {n} samples")


def entry_text(path: Path, key: str) -> str:
    with h5py.File(path, "r", swmr=True) as f:
        return f[f"entry/{key}"][()].decode()


@pytest.mark.slow
def test_dry_run_and_list_params_move_nothing(tmp_path):
    out = tmp_path / "never.h5"
    r = rigctl("run", "slide_hold_slide", "--dry-run", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "estimated" in r.stdout and "dry run: nothing moved" in r.stdout
    assert not out.exists()
    r = rigctl("run", "tlre", "--list-params")
    assert r.returncode == 0 and "velocity_m_s" in r.stdout and "1.3e-06" in r.stdout


@pytest.mark.slow
def test_a_limit_beyond_the_rig_is_refused_by_the_dry_run(tmp_path):
    out = tmp_path / "never.h5"
    r = rigctl("run", "tlre", "--param", "fn_N=5000", "--speed", "max", "--out", str(out))
    assert r.returncode == 2
    assert "dry run refused" in r.stderr and "6000 N exceeds the limit 800 N" in r.stderr
    assert not out.exists()


@pytest.mark.slow
def test_an_unusable_output_path_is_refused_before_motion(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    r = rigctl("run", "tlre", "--speed", "max", "--out", str(blocker / "run.h5"), *SHORT)
    assert r.returncode == 2
    assert "a_file" in r.stderr and "not a folder" in r.stderr
    assert "completed" not in r.stdout


@pytest.mark.slow
def test_ctrl_c_brings_the_rig_to_a_safe_state_and_records_aborted(tmp_path):
    out = tmp_path / "ctrlc.h5"
    with started("run", "tlre", "--speed", "20", "--no-camera", "--out", str(out), *SHORT) as proc:
        wait_for_samples(out, 20 * 1024, proc)  # about 20 s of rig time: loaded, sliding
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "safe state" in stderr
    assert entry_text(out, "status") == "aborted"
    assert "Ctrl-C" in entry_text(out, "error")
    with RunReader(out) as r:
        d = r.read_daq()
        names = [e.name for e in r.events()]
    assert "safe_state" in names
    assert d["fn_N"].max() > 250.0  # it had been loaded
    assert abs(d["fn_N"][-1]) < 1.0  # and the load was released before the file closed


@pytest.mark.slow
def test_a_second_ctrl_c_escalates_to_the_emergency_stop_and_still_closes_the_file(tmp_path):
    """The second Ctrl-C emergency-stops both stages; the file still ends with its status and end
    time, not 'running'."""
    out = tmp_path / "ctrlc2.h5"
    with started("run", "tlre", "--speed", "20", "--no-camera", "--out", str(out), *SHORT) as proc:
        wait_for_samples(out, 20 * 1024, proc)
        proc.send_signal(signal.SIGINT)
        time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "EMERGENCY STOP" in stderr
    assert entry_text(out, "status") == "aborted"  # closed with its status, not 'running'
    assert "Ctrl-C" in entry_text(out, "error")
    with RunReader(out) as r:
        assert "safe_state" in [e.name for e in r.events()]


@pytest.mark.slow
def test_sigusr1_while_the_rig_starts_does_not_kill_the_run(tmp_path):
    """Pause/resume asked before the run exists are kept; SIGUSR1's default action (killing the
    process, exit -10, no file) never applies."""
    out = tmp_path / "usr1.h5"
    with started("run", "tlre", "--speed", "max", "--no-camera", "--out", str(out), *SHORT) as proc:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline and not out.exists():
            if os.path.exists(f"/proc/{proc.pid}/status"):
                with open(f"/proc/{proc.pid}/status") as fh:
                    caught = next((ln for ln in fh if ln.startswith("SigCgt:")), "SigCgt: 0")
                if int(caught.split()[1], 16) & (1 << (signal.SIGUSR1 - 1)):
                    break  # the command has installed its handler: send now, before the rig runs
            time.sleep(0.01)
        proc.send_signal(signal.SIGUSR1)
        time.sleep(1.0)
        proc.send_signal(signal.SIGUSR2)
        _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert entry_text(out, "status") == "completed"
    assert "pause" in stderr and "resume" in stderr  # said, whichever phase caught them


@pytest.mark.slow
def test_pause_and_resume_during_the_run_are_said(tmp_path):
    out = tmp_path / "pr.h5"
    with started("run", "tlre", "--speed", "20", "--no-camera", "--out", str(out), *SHORT) as proc:
        wait_for_samples(out, 2 * 1024, proc)
        proc.send_signal(signal.SIGUSR1)
        time.sleep(0.5)
        proc.send_signal(signal.SIGUSR2)
        _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert "paused (SIGUSR1; SIGUSR2 resumes)" in stderr and "resumed (SIGUSR2)" in stderr


@pytest.mark.slow
def test_sigkill_leaves_a_readable_file_missing_at_most_half_a_second(tmp_path):
    out = tmp_path / "killed.h5"
    with started("run", "tlre", "--speed", "1", "--out", str(out), *SHORT) as proc:
        wait_for_samples(out, 3 * 1024, proc)
        time.sleep(1.3)  # a moment between flushes, not right after one
        t_kill = time.monotonic()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    with RunReader(out) as r:  # opens: the file is consistent
        blocks = r.blocks()
        d = r.read_daq()
        assert r.status == "running"  # never closed: the file says so
    host_s = blocks["host_time_s"]
    assert np.all(np.isfinite(host_s))
    # host_time is CLOCK_MONOTONIC, system-wide on Linux: comparable with this process's clock
    lost_s = t_kill - float(host_s[-1])
    assert 0.0 <= lost_s <= 0.5, lost_s
    assert np.all(np.diff(d["t_s"]) > 0)
    assert np.all(np.isfinite(d["ft_N"]))


def _limit_file_size(limit_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write beyond fails with EFBIG instead

    return apply


@pytest.mark.skipif(not hasattr(resource, "RLIMIT_FSIZE"), reason="needs RLIMIT_FSIZE")
@pytest.mark.slow
def test_a_full_disk_mid_run_fails_safely_and_keeps_what_was_written(tmp_path):
    """The file-size limit stands in for a full disk: writes beyond it fail (EFBIG) like ENOSPC.

    The run writes about 3.1 MB (33 s of rig time). The 2 MB limit falls mid-run, after some
    19,000 samples. At ``--speed 20`` a flush interval (0.25 s) carries at most about 5,000
    samples (some 370 kB), so several flushes land before the limit. Before this, the test ran
    at ``--speed max`` with a 3 MB limit: a fast machine put 33,728 samples in the first
    interval, past that limit, and no row was flushed to keep."""
    out = tmp_path / "full.h5"
    proc = subprocess.run([*RIGCTL, "run", "tlre", "--speed", "20", "--no-camera", "--out", str(out),
                           *SHORT], capture_output=True, text=True, timeout=120,
                          preexec_fn=_limit_file_size(2_000_000))
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "run file writer" in proc.stderr or "writer" in proc.stderr
    assert "failed" in proc.stdout
    with RunReader(out) as r:  # what had been flushed is still readable
        assert r.n_samples > 10 * 1024
