"""No process outlives `rigctl model diagnose`: run it as a real command and watch its descendants.

The candidate fits run in forked worker processes (rigctl/workbench/parallel.py). Whether the
command finishes, is interrupted with Ctrl-C (SIGINT to the whole process group, as a terminal
sends it), is terminated (SIGTERM) or killed (SIGKILL), no worker may be left running, and the
interrupted command ends with one line, not a traceback.

To have workers busy when the signal arrives, one candidate is a plug-in effect whose simulation is
slow (a force-sensor zero drift that takes 0.5 s per simulation: its fit runs for tens of seconds,
like a candidate fit on a long real record).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest

from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign, write_campaign

SLOW_PLUGIN = textwrap.dedent('''
    """A force sensor whose zero drifts linearly in time, simulated slowly (0.5 s per run)."""
    import time

    from rigctl.model import Effect, ParamSpec


    class SlowSensorDrift(Effect):
        name = "slow_sensor_drift"
        summary = "the force sensor's zero drifts linearly with time (slow to simulate)"
        signature = "peaks and troughs drift with time while stick times stay"
        reveal_protocol = "a long hold at zero tangential load recording Ft"
        params = (ParamSpec("rate_N_per_s", 0.01, -1.0, 1.0, "N/s", "zero drift rate", off=0.0),)

        def transform_output(self, result, values):
            time.sleep(0.5)
            result.ft_N += values["rate_N_per_s"] * (result.t_s - result.t_s[0])
''')


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("procs")
    model = build_model("paper", effects=["wear"])
    write_campaign(simulate_campaign(model, "tlre", seed=5, duration_scale=0.4), folder / "camp")
    plugin = folder / "slow_drift.py"
    plugin.write_text(SLOW_PLUGIN)
    return folder / "camp", plugin


def _diagnose(campaign: tuple[Path, Path], candidates: str) -> subprocess.Popen[str]:
    camp, plugin = campaign
    cmd = [sys.executable, "-m", "rigctl.cli.main", "model", "diagnose", str(camp),
           "--effect-file", str(plugin), "--candidates", candidates, "--workers", "2"]
    # a session of its own: the process group a terminal would have, and os.killpg reaches it all;
    # SIGINT at its default action and unblocked, as in a terminal's foreground job (a child
    # inherits an ignored or blocked SIGINT from whatever started the test run, and Python then
    # never raises KeyboardInterrupt: twice in full-suite runs the command ignored the Ctrl-C)
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_sigint_default)


def _sigint_default() -> None:
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _descendants(pid: int) -> dict[int, psutil.Process]:
    try:
        return {c.pid: c for c in psutil.Process(pid).children(recursive=True)}
    except psutil.NoSuchProcess:
        return {}


def _wait_for_workers(proc: subprocess.Popen[str], n: int, timeout_s: float = 90.0
                      ) -> dict[int, psutil.Process]:
    seen: dict[int, psutil.Process] = {}
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end and proc.poll() is None:
        now = _descendants(proc.pid)
        seen.update(now)
        if len(now) >= n:
            return seen
        time.sleep(0.05)
    pytest.fail(f"no {n} workers within {timeout_s} s (exit code {proc.poll()})")


def _survivors(seen: dict[int, psutil.Process]) -> list[str]:
    """Processes among ``seen`` still running (zombies do not count: they have exited)."""
    time.sleep(0.5)
    alive = []
    for p in seen.values():
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                alive.append(f"{p.pid} (parent {p.ppid()}): {' '.join(p.cmdline())}")
                p.kill()  # do not leave it behind for the next test either
        except psutil.NoSuchProcess:
            pass
    return alive


def _watch_until_exit(proc: subprocess.Popen[str], seen: dict[int, psutil.Process],
                      timeout_s: float = 60.0) -> tuple[str, str]:
    t_end = time.monotonic() + timeout_s
    while proc.poll() is None and time.monotonic() < t_end:
        seen.update(_descendants(proc.pid))
        time.sleep(0.05)
    out, err = proc.communicate(timeout=5)
    return out, err


def test_no_worker_remains_after_diagnose_finishes(campaign):
    proc = _diagnose(campaign, "wear,probe_drift")
    seen = _wait_for_workers(proc, 1)
    out, err = _watch_until_exit(proc, seen, timeout_s=120.0)
    assert proc.returncode == 0, err
    assert "verdict:" in out
    assert _survivors(seen) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_diagnose_leaves_no_worker_and_says_so_in_one_line(campaign, sig):
    proc = _diagnose(campaign, "slow_sensor_drift,wear,probe_drift")
    seen = _wait_for_workers(proc, 2)
    time.sleep(1.0)
    # the slow candidate is fitting (the slowest is started first; its fit takes tens of seconds)
    assert any(p.is_running() for p in _descendants(proc.pid).values())
    if sig == signal.SIGINT:
        os.killpg(proc.pid, sig)  # Ctrl-C at a terminal: the whole foreground process group
    else:
        proc.send_signal(sig)  # a job manager's stop: the command only
    _out, err = _watch_until_exit(proc, seen, timeout_s=30.0)
    assert proc.returncode == (130 if sig == signal.SIGINT else 143), err
    last = err.strip().splitlines()[-1]
    assert last == ("rigctl: interrupted" if sig == signal.SIGINT
                    else "rigctl: terminated (SIGTERM)")
    assert "Traceback" not in err, err
    assert _survivors(seen) == []


def test_workers_die_with_a_killed_diagnose(campaign):
    """SIGKILL gives the command no chance to clean up: the workers end themselves (Linux)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("the parent-death signal is Linux only")
    proc = _diagnose(campaign, "slow_sensor_drift,wear")
    seen = _wait_for_workers(proc, 2)
    proc.kill()
    proc.wait(timeout=10)
    assert _survivors(seen) == []
