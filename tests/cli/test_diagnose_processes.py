"""No process outlives `rigctl model diagnose`: run it as a command and watch its descendants.

The candidate fits run in forked worker processes (rigctl/workbench/parallel.py). Whether the
command finishes, is interrupted with Ctrl-C (SIGINT to the whole process group, as a terminal
sends it), is terminated (SIGTERM) or killed (SIGKILL), no worker may be left running, and the
interrupted command ends with one line, not a traceback.

To have workers busy when the signal arrives, the candidates are plug-in effects whose simulation
is *held* in a worker process (like a candidate fit on a long real record, but without a sleep):
the worker writes its pid to a file the test names and waits for ever; the test signals the
command once every worker holds. In the command's own process (the cost probe before the fits)
the effects simulate at once.

The command is started in one of two ways:

* ``forked`` (the fast tier): a helper process that has imported what the command imports (about
  5 CPU seconds, paid once per module) forks each command: a process of its own session, SIGINT
  and SIGTERM at their defaults, running ``rigctl.cli.main.main`` with the command's arguments;
* ``executed`` (the slow tier): ``python -m rigctl.cli.main`` as a new process, as a user starts it.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import psutil
import pytest

from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign, write_campaign

WAIT_S = 120.0  # longest wait for the command or its workers (a bound for a broken run, not a pace)
HELD_CANDIDATES = "held_sensor_drift,held_sensor_gain"

HELD_PLUGIN = textwrap.dedent('''
    """Two force-sensor effects whose simulation holds in a worker process (a test's stand-in for
    a candidate fit that runs for minutes): the worker appends its pid to the file named by
    $RIGCTL_TEST_HELD and waits for ever. In the command's own process it simulates at once."""
    import multiprocessing
    import os
    import threading

    from rigctl.model import Effect, ParamSpec


    def hold():
        if multiprocessing.parent_process() is None:  # the command itself (the cost probe)
            return
        with open(os.environ["RIGCTL_TEST_HELD"], "a") as f:
            f.write(f"{os.getpid()}\\n")
        threading.Event().wait()  # until the worker is stopped or killed


    class HeldSensorDrift(Effect):
        name = "held_sensor_drift"
        summary = "the force sensor's zero drifts linearly with time (held in a worker)"
        signature = "peaks and troughs drift with time while stick times stay"
        reveal_protocol = "a long hold at zero tangential load recording Ft"
        params = (ParamSpec("rate_N_per_s", 0.01, -1.0, 1.0, "N/s", "zero drift rate", off=0.0),)

        def transform_output(self, result, values):
            hold()
            result.ft_N += values["rate_N_per_s"] * (result.t_s - result.t_s[0])


    class HeldSensorGain(Effect):
        name = "held_sensor_gain"
        summary = "the force sensor reads a fixed fraction high or low (held in a worker)"
        signature = "every force level scaled alike"
        reveal_protocol = "a dead-weight calibration"
        params = (ParamSpec("gain_error", 0.01, -0.5, 0.5, "1", "relative gain error", off=0.0),)

        def transform_output(self, result, values):
            hold()
            result.ft_N *= 1.0 + values["gain_error"]
''')

FORK_SERVER = textwrap.dedent('''
    """Imports what `rigctl model diagnose` imports and says "ready"; then for each request on
    stdin (JSON: argv, env, stdout and stderr paths) forks a command: a session of its own, SIGINT
    and SIGTERM at their defaults, stdin /dev/null, running rigctl.cli.main.main(argv) to the
    interpreter's exit. Writes the command's pid, then its exit code (negative: the signal that
    ended it), one line each."""
    import json
    import os
    import signal
    import sys

    import rigctl.cli.cmd_model
    import rigctl.records.dataset
    import rigctl.workbench.compare
    import rigctl.workbench.diagnose
    import rigctl.workbench.model_choice
    import rigctl.workbench.report
    from rigctl.cli.main import main

    os.write(1, b"ready\\n")
    for line in sys.stdin:
        req = json.loads(line)
        pid = os.fork()
        if pid == 0:
            os.setsid()
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
            signal.signal(signal.SIGINT, signal.default_int_handler)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            for fd, path in ((1, req["stdout"]), (2, req["stderr"])):
                os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
            os.environ.update(req["env"])
            sys.argv = ["rigctl", *req["argv"]]
            sys.exit(main(req["argv"]))
        os.write(1, f"{pid}\\n".encode())
        os.write(1, f"{os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])}\\n".encode())
''')


class ForkServer:
    """The helper process of the ``forked`` commands (module docstring)."""

    def __init__(self, log: Path) -> None:
        self.log = log
        with log.open("w") as err:
            self.proc = subprocess.Popen([sys.executable, "-c", FORK_SERVER], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=err, start_new_session=True)
        self._buf = b""
        assert self.line(WAIT_S) == "ready", self.log.read_text()

    def line(self, timeout_s: float) -> str | None:
        """Its next line, or None if none within ``timeout_s``."""
        assert self.proc.stdout is not None
        t_end = time.monotonic() + timeout_s
        while b"\n" not in self._buf:
            left = max(0.0, t_end - time.monotonic())
            if not select.select([self.proc.stdout], [], [], left)[0]:
                return None
            chunk = os.read(self.proc.stdout.fileno(), 4096)
            assert chunk, f"the fork server ended: {self.log.read_text()}"
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return line.decode()

    def start(self, argv: list[str], env: dict[str, str], out: Path, err: Path) -> int:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"argv": argv, "env": env, "stdout": str(out),
                                          "stderr": str(err)}).encode() + b"\n")
        self.proc.stdin.flush()
        pid = self.line(WAIT_S)
        assert pid is not None, f"no command forked within {WAIT_S} s"
        return int(pid)

    def close(self) -> None:
        self.proc.kill()  # it holds nothing (its commands are over), and its exit takes seconds
        self.proc.wait()
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.close()
        self.proc.stdout.close()


class Command:
    """A started `rigctl model diagnose`: its pid, its exit code once it ended, its output."""

    def __init__(self, pid: int, poll: Callable[[], int | None], out: Path, err: Path) -> None:
        self.pid = pid
        self._poll = poll
        self._out, self._err = out, err
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self._poll()
        return self.returncode

    def output(self) -> tuple[str, str]:
        return self._out.read_text(), self._err.read_text()


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("procs")
    model = build_model("paper", effects=["wear"])
    write_campaign(simulate_campaign(model, "tlre", seed=5, duration_scale=0.4), folder / "camp")
    plugin = folder / "held_sensor.py"
    plugin.write_text(HELD_PLUGIN)
    return folder / "camp", plugin


@pytest.fixture(scope="module")
def fork_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ForkServer]:
    server = ForkServer(tmp_path_factory.mktemp("fork_server") / "stderr.txt")
    yield server
    server.close()


@pytest.fixture(params=["forked", pytest.param("executed", marks=pytest.mark.slow)])
def launch(request: pytest.FixtureRequest, campaign: tuple[Path, Path], tmp_path: Path
           ) -> Iterator[Callable[..., Command]]:
    """Starts `rigctl model diagnose` on the campaign with the held plug-ins, two workers; a
    command still running at the end of the test is killed with its process group."""
    started: list[Command] = []
    camp, plugin = campaign
    server: ForkServer | None = (request.getfixturevalue("fork_server")
                                 if request.param == "forked" else None)
    env = {"RIGCTL_TEST_HELD": str(tmp_path / "held.txt")}

    def start(candidates: str, *extra: str) -> Command:
        argv = ["model", "diagnose", str(camp), "--effect-file", str(plugin),
                "--candidates", candidates, "--workers", "2", *extra]
        out, err = tmp_path / f"stdout{len(started)}.txt", tmp_path / f"stderr{len(started)}.txt"
        if server is not None:

            def exit_code() -> int | None:
                line = server.line(0.0)
                return None if line is None else int(line)

            cmd = Command(server.start(argv, env, out, err), exit_code, out, err)
        else:
            # a session of its own: the process group a terminal would have, and os.killpg
            # reaches it all; SIGINT at its default action and unblocked, as in a terminal's
            # foreground job (a child inherits an ignored or blocked SIGINT from whatever started
            # the test run, and Python then never raises KeyboardInterrupt)
            with out.open("w") as o, err.open("w") as e:
                proc = subprocess.Popen([sys.executable, "-m", "rigctl.cli.main", *argv],
                                        stdout=o, stderr=e, env={**os.environ, **env},
                                        start_new_session=True, preexec_fn=_sigint_default)
            cmd = Command(proc.pid, proc.poll, out, err)
        started.append(cmd)
        return cmd

    yield start
    for cmd in started:
        if cmd.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(cmd.pid, signal.SIGKILL)
            t_end = time.monotonic() + WAIT_S
            while cmd.poll() is None and time.monotonic() < t_end:  # the fork server's next line
                time.sleep(0.05)


def _sigint_default() -> None:
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _descendants(pid: int) -> dict[int, psutil.Process]:
    try:
        return {c.pid: c for c in psutil.Process(pid).children(recursive=True)}
    except psutil.NoSuchProcess:
        return {}


def _wait_until_held(cmd: Command, held: Path, n: int) -> dict[int, psutil.Process]:
    """Wait until ``n`` of the command's workers hold in a candidate's simulation; the command's
    descendants then."""
    t_end = time.monotonic() + WAIT_S
    while time.monotonic() < t_end and cmd.poll() is None:
        pids = {int(p) for p in held.read_text().split()} if held.exists() else set()
        seen = _descendants(cmd.pid)
        if len(pids) >= n:
            assert pids <= set(seen), f"held {pids}, the command's descendants {set(seen)}"
            return seen
        time.sleep(0.05)
    pytest.fail(f"no {n} workers held within {WAIT_S} s (exit code {cmd.poll()}): "
                f"{cmd.output()[1][-2000:]}")


def _watch_until_exit(cmd: Command, seen: dict[int, psutil.Process], timeout_s: float = 60.0
                      ) -> tuple[int, str, str]:
    """The command's exit code and output, and every descendant it had on the way into ``seen``."""
    t_end = time.monotonic() + timeout_s
    while cmd.poll() is None:
        assert time.monotonic() < t_end, (f"the command did not end within {timeout_s} s; its "
                                          f"stderr ends: {cmd.output()[1][-2000:]}")
        seen.update(_descendants(cmd.pid))
        time.sleep(0.05)
    out, err = cmd.output()
    return cmd.returncode, out, err  # type: ignore[return-value]


def _survivors(seen: dict[int, psutil.Process], timeout_s: float = 10.0) -> list[str]:
    """Processes among ``seen`` still running once they had ``timeout_s`` to end (zombies do not
    count: they have exited); those are killed, not to be left behind for the next test."""

    def alive() -> list[psutil.Process]:
        out = []
        for p in seen.values():
            with contextlib.suppress(psutil.NoSuchProcess):
                if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                    out.append(p)
        return out

    t_end = time.monotonic() + timeout_s
    while alive() and time.monotonic() < t_end:
        time.sleep(0.05)
    left = []
    for p in alive():
        with contextlib.suppress(psutil.NoSuchProcess):
            left.append(f"{p.pid} (parent {p.ppid()}): {' '.join(p.cmdline())}")
            p.kill()
    return left


@pytest.mark.slow
@pytest.mark.parametrize("launch", ["executed"], indirect=True)
def test_no_worker_remains_after_diagnose_finishes(launch):
    """The real fits (about 10 s of workers' time): every worker ended with the command."""
    cmd = launch("wear,probe_drift")
    seen: dict[int, psutil.Process] = {}
    code, out, err = _watch_until_exit(cmd, seen, timeout_s=WAIT_S)
    assert code == 0, err
    assert "verdict:" in out
    assert "fitted wear" in err and "screened probe_drift" in err  # only a significant screen
    # is fitted fully (docs/workbench.md section 5)
    assert seen  # the candidates were fitted in workers
    assert _survivors(seen) == []


@pytest.mark.slow
def test_no_worker_remains_after_the_run_s_time_limit_stops_held_candidates(launch, tmp_path):
    """Both workers hold in the candidates' screen until the run's time limit (--max-time) stops
    them: the command ends with its result, says that the limit ended it, and leaves no worker."""
    cmd = launch(HELD_CANDIDATES, "--max-time", "5")
    seen = _wait_until_held(cmd, tmp_path / "held.txt", 2)
    code, out, err = _watch_until_exit(cmd, seen)
    assert code == 0, err
    assert "verdict:" in out
    assert "time limit" in err and "stopped:" in out, (out, err)
    assert _survivors(seen) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_diagnose_leaves_no_worker_and_says_so_in_one_line(launch, tmp_path, sig):
    cmd = launch(HELD_CANDIDATES)
    seen = _wait_until_held(cmd, tmp_path / "held.txt", 2)  # both workers in a candidate's fit
    if sig == signal.SIGINT:
        os.killpg(cmd.pid, sig)  # Ctrl-C at a terminal: the whole foreground process group
    else:
        os.kill(cmd.pid, sig)  # a job manager's stop: the command only
    code, _out, err = _watch_until_exit(cmd, seen, timeout_s=30.0)
    assert code == (130 if sig == signal.SIGINT else 143), err
    last = err.strip().splitlines()[-1]
    assert last == ("rigctl: interrupted" if sig == signal.SIGINT
                    else "rigctl: terminated (SIGTERM)")
    assert "Traceback" not in err, err
    assert _survivors(seen) == []


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_auto_leaves_no_worker_within_2_s(launch, tmp_path, sig):
    """--auto's searches and screens evaluate in their own pools: Ctrl-C or SIGTERM while both
    workers hold in a candidate's screen ends the command and every worker within 2 s."""
    cmd = launch(HELD_CANDIDATES, "--auto")
    seen = _wait_until_held(cmd, tmp_path / "held.txt", 2)
    t0 = time.monotonic()
    if sig == signal.SIGINT:
        os.killpg(cmd.pid, sig)
    else:
        os.kill(cmd.pid, sig)
    code, _out, err = _watch_until_exit(cmd, seen, timeout_s=30.0)
    ended_s = time.monotonic() - t0
    # what is still running 2 s after the signal is a survivor (killed, and the test fails)
    assert _survivors(seen, timeout_s=max(0.0, 2.0 - (time.monotonic() - t0))) == []
    assert ended_s <= 2.0 + 0.5, ended_s  # the watch polls every 50 ms, psutil costs its own
    assert code == (130 if sig == signal.SIGINT else 143), err
    assert "Traceback" not in err, err


def test_workers_die_with_a_killed_diagnose(launch, tmp_path):
    """SIGKILL gives the command no chance to clean up: the workers end themselves (Linux)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("the parent-death signal is Linux only")
    cmd = launch(HELD_CANDIDATES)
    seen = _wait_until_held(cmd, tmp_path / "held.txt", 2)
    os.kill(cmd.pid, signal.SIGKILL)
    code, _out, _err = _watch_until_exit(cmd, {}, timeout_s=10.0)
    assert code == -signal.SIGKILL
    assert _survivors(seen) == []
