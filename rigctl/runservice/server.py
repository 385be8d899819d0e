"""The run service: owns the open rig and runs protocols in its own process; GUIs are clients.

A protocol run must outlive its window: if the GUI crashes or is killed mid-run, the run goes on in
this process, the rig ends in the state the protocol (or its safe state) leaves it, and the run file is
closed with its status, exactly as with ``rigctl run``. The service is started by ``rigctl gui`` in a
new session (so a signal to the GUI's process group does not reach it), or by hand:
``python -m rigctl.runservice --backend sim --speed 10``.

* One rig, opened at start (``rigctl.rigs.open_rig``) and closed at exit.
* One run at a time, in a worker thread, built exactly as ``rigctl run`` builds it (same Runner,
  layouts, force limit, description with ``started_from`` in the metadata).
* Clients (any number) connect over a Unix socket (:mod:`rigctl.runservice.wire`), each
  authenticated in its own thread within 5 s (:mod:`rigctl.runservice.auth`). Each has a sender
  thread with its own bounded queue: a slow or frozen client loses its own live data (counted), never
  delays the run or other clients; control messages (plan, progress, outcome) are never dropped.
* A client that disappears mid-run changes nothing, unless ``--orphan abort``: then the run is aborted
  (safe state: tangential stage stopped, normal load released, file closed ``aborted``) once no client
  has been connected for ``--orphan-grace-s``.
* SIGTERM/SIGINT/SIGQUIT abort the run (safe state) and stop the service; SIGHUP (the terminal it
  was started from closing) is ignored from the start: the run goes on. The service also stops by
  itself after ``--idle-exit-s`` with no run and no client.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import signal
import sys
import threading
import time
from collections import deque
from multiprocessing.connection import Client, Connection, Listener
from pathlib import Path
from types import FrameType
from typing import Any

from experiments.context import Controls
from experiments.errors import PlanError
from experiments.params import parse_assignments
from experiments.runner import Runner, get_protocol
from rigctl.acquisition import Acquisition
from rigctl.config import RigConfig
from rigctl.errors import InputError
from rigctl.rigs import OpenRig, open_rig
from rigctl.runservice.auth import authenticate
from rigctl.runservice.culprits import refusal_culprits
from rigctl.runservice.devices import RigSnapshot, jog, reset_emergency_stop, snapshot
from rigctl.runservice.events import WarningForwarder, drop_events
from rigctl.runservice.frames import start_forwarding
from rigctl.runservice.messages import command_problem
from rigctl.runservice.private import ServiceFolderError, check_private_folder
from rigctl.runservice.queue import RunQueue
from rigctl.runservice.wire import LIVE_COLUMNS, Address, JobSpec, RunResult, ServiceState

_log = logging.getLogger("rigctl.runservice")

LIVE_QUEUE_MAX = 256
"""Live-data messages a client may have waiting before its oldest are dropped."""
LIVE_FRAME_QUEUE_MAX = 4
"""Live camera images (``frame`` messages) a client may have waiting before its oldest are dropped."""
DROP_CHECK_INTERVAL_S = 1.0
"""How often the acquisition's drop counters are compared for ``dropped data`` events."""
ESTOP_REASON = "emergency stop"
SNAPSHOT_INTERVAL_S = 0.4
"""Device status sent to clients this often (the Devices tab)."""
FORWARD_JOIN_S = 5.0
"""How long a run's end waits for its live forwarders' last items before ``done`` is sent."""
FIRST_CLIENT_WAIT_S = 60.0
"""A new service waits at least this long for its first client before it stops as idle."""


class _ClientLink:
    """One connected client: a reader (commands in) and a sender with a bounded live queue."""

    def __init__(self, conn: Connection, service: RunService) -> None:
        self.conn = conn
        self.service = service
        self._queue: deque[tuple[str, Any]] = deque()
        self._cond = threading.Condition()
        self.dropped_live = 0
        self.closed = False
        threading.Thread(target=self._send_loop, name="runservice-send", daemon=True).start()
        threading.Thread(target=self._read_loop, name="runservice-read", daemon=True).start()

    def send(self, kind: str, payload: Any) -> None:
        with self._cond:
            if self.closed:
                return
            bound = {"daq": LIVE_QUEUE_MAX, "frame": LIVE_FRAME_QUEUE_MAX}.get(kind)
            if bound is not None:
                live = sum(1 for k, _ in self._queue if k == kind)
                if live >= bound:
                    for i, (k, _) in enumerate(self._queue):
                        if k == kind:
                            del self._queue[i]
                            self.dropped_live += 1
                            break
            self._queue.append((kind, payload))
            self._cond.notify()

    def _send_loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self.closed:
                    self._cond.wait()
                if self.closed:
                    return
                item = self._queue.popleft()
            try:
                self.conn.send(item)
            except (OSError, EOFError, ValueError):
                self.close()
                return

    def _read_loop(self) -> None:
        """Commands in until the connection ends; a malformed one is answered with one error line
        (:mod:`rigctl.runservice.messages`) and the connection goes on."""
        try:
            while True:
                try:
                    message = self.conn.recv()
                except (OSError, EOFError):
                    return
                except Exception as exc:  # a message that does not unpickle (it was read whole)
                    self._refuse(f"cannot be read ({type(exc).__name__}: {exc})")
                    continue
                problem = command_problem(message)
                if problem is not None:
                    self._refuse(problem)
                    continue
                kind, payload = message
                try:
                    self.service.command(kind, payload, self)
                except Exception as exc:  # a payload of the wrong shape for its command
                    self._refuse(f"{kind!r} failed: {type(exc).__name__}: {exc}")
        finally:
            self.close()

    def _refuse(self, problem: str) -> None:
        _log.warning("malformed message from a client: %s", problem)
        self.send("log", ("error", f"run service: malformed message refused: {problem}"))

    def close(self) -> None:
        with self._cond:
            if self.closed:
                return
            self.closed = True
            self._cond.notify_all()
        with contextlib.suppress(Exception):
            self.conn.close()
        self.service.client_gone(self)


class RunService:
    """Serve one open rig to GUI clients on ``address`` until :meth:`stop` (or idle)."""

    def __init__(self, rig: OpenRig, backend: str, address: Address, *, speed_text: str = "1",
                 idle_exit_s: float = 10.0, orphan: str = "continue", orphan_grace_s: float = 5.0) -> None:
        if orphan not in ("continue", "abort"):
            raise ValueError(f"orphan policy must be 'continue' or 'abort', got {orphan!r}")
        self.rig = rig
        self.backend = backend
        self.address = address
        self.speed_text = speed_text
        self.idle_exit_s = idle_exit_s
        self.orphan = orphan
        self.orphan_grace_s = orphan_grace_s
        self.state = ServiceState(backend=backend, speed=rig.speed, rig=rig.config.rig.name,
                                  pid=os.getpid())
        self._clients: list[_ClientLink] = []
        self._lock = threading.Lock()
        self._controls: Controls | None = None
        self._runner: Runner | None = None
        self._thread: threading.Thread | None = None
        self._forwarders: list[threading.Thread] = []
        """The live-data forwarders of the current run, joined before its ``done`` is sent."""
        self._stop = threading.Event()
        self._last_client_s = time.monotonic()
        self._idle_since = time.monotonic()
        self._listener: Listener | None = None
        self._ever_client = False
        self._last_snapshot_s = 0.0
        self._queue = RunQueue()
        self.state.queue = self._queue.state()

    # ------------------------------------------------------------------ lifecycle
    def serve(self) -> None:
        key = self.address.new_key()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.address.socket)
        # no authkey here: accept() would run the challenge itself, and one connection that never
        # answers it would block every other client; each is authenticated in its own thread
        # bound and listening under a temporary name, then renamed into place: a client that sees
        # the socket can connect at once (bind and listen are two calls, and a connect between
        # them is refused)
        staging = f"{self.address.socket}.{os.getpid()}.tmp"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(staging)
        self._listener = Listener(staging, family="AF_UNIX")
        os.chmod(staging, 0o600)
        os.replace(staging, self.address.socket)
        threading.Thread(target=self._accept_loop, args=(key,), name="runservice-accept",
                         daemon=True).start()
        self._log("info", f"run service {os.getpid()} on {self.backend} ({self.address.socket})")
        try:
            while not self._stop.wait(0.2):
                self._watch()
        finally:
            self._finish()

    def stop(self, reason: str = "run service stopped") -> None:
        """Abort any run (safe state) and end :meth:`serve` once the run has finished."""
        self.abort(reason)
        self._stop.set()

    def _finish(self) -> None:
        if self._controls is not None:
            self._controls.abort("run service stopped")
            self._controls.resume()
        if self._thread is not None:
            self._thread.join(120.0)
        if self._listener is not None:
            with contextlib.suppress(Exception):
                self._listener.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.address.socket)
        for c in list(self._clients):
            c.close()

    def _watch(self) -> None:
        now = time.monotonic()
        with self._lock:
            has_clients = bool(self._clients)
        if has_clients and now - self._last_snapshot_s >= SNAPSHOT_INTERVAL_S:
            self._last_snapshot_s = now
            self._broadcast("devices", self.devices_snapshot())
        if has_clients:
            self._last_client_s = now
            self._ever_client = True
        busy = self.state.busy
        if busy:
            self._idle_since = now
            if (self.orphan == "abort" and not has_clients
                    and now - self._last_client_s > self.orphan_grace_s
                    and self._controls is not None and not self._controls.aborted):
                self._log("warning", "no client connected: aborting the run (--orphan abort)")
                self.abort("aborted: the operator's window went away")
        elif not has_clients and now - max(self._idle_since, self._last_client_s) > (
                self.idle_exit_s if self._ever_client else max(self.idle_exit_s, FIRST_CLIENT_WAIT_S)):
            self._log("info", "idle with no client: stopping")
            self._stop.set()

    def _accept_loop(self, key: bytes) -> None:
        assert self._listener is not None
        while not self._stop.is_set():
            try:
                conn = self._listener.accept()
            except Exception:  # closed listener
                if self._stop.is_set():
                    return
                continue
            threading.Thread(target=self._admit, args=(conn, key), name="runservice-auth",
                             daemon=True).start()

    def _admit(self, conn: Connection, key: bytes) -> None:
        """Authenticate one connection (within AUTH_TIMEOUT_S), then serve it as a client."""
        refused = authenticate(conn, key)
        if refused is not None:
            _log.warning("a connection %s; closed", refused)
            return
        if self._stop.is_set():
            conn.close()
            return
        link = _ClientLink(conn, self)
        with self._lock:
            self._clients.append(link)
        link.send("hello", self.state)

    def client_gone(self, link: _ClientLink) -> None:
        with self._lock:
            if link in self._clients:
                self._clients.remove(link)
            remaining = len(self._clients)
        if self.state.busy and remaining == 0:
            self._log("warning", "the last client went away during a run; the run goes on"
                      if self.orphan == "continue" else
                      f"the last client went away during a run; aborting in {self.orphan_grace_s:g} s "
                      "unless one reconnects")

    def _broadcast(self, kind: str, payload: Any) -> None:
        with self._lock:
            clients = list(self._clients)
        for c in clients:
            c.send(kind, payload)

    def _log(self, level: str, text: str) -> None:
        getattr(_log, level if level != "warning" else "warning")(text)
        self.state.log = [*self.state.log[-49:], (level, text)]
        self._broadcast("log", (level, text))

    # ------------------------------------------------------------------ commands (reader threads)
    def command(self, kind: str, payload: Any, link: _ClientLink) -> None:
        if kind == "start":
            self.start(payload)
        elif kind == "pause":
            if self._controls is not None and self.state.busy:
                self._controls.pause()
                self.state.paused = True
                self._broadcast("state", self.state)
                self._log("info", "run paused by the operator (the stages hold; recording goes on)")
        elif kind == "resume":
            if self._controls is not None and self.state.busy:
                self._controls.resume()
                self.state.paused = False
                self._broadcast("state", self.state)
                self._log("info", "run resumed by the operator")
        elif kind == "abort":
            self.abort(str(payload or "aborted by the operator"))
        elif kind == "estop":
            self.emergency_stop(str(payload or ESTOP_REASON))
        elif kind == "jog":
            link.send("jog_result", self.jog(*payload))
        elif kind == "reset_estop":
            self.reset_emergency_stop()
        elif kind == "state":
            link.send("state", self.state)
        elif kind.startswith("queue_"):
            self.queue_command(kind, payload)
        elif kind == "shutdown":
            self.stop("run service shut down by the operator")
        else:
            link.send("log", ("error", f"unknown command {kind!r}"))

    def queue_command(self, kind: str, payload: Any) -> None:
        """``queue_add|remove|move|start|abort|clear`` (:mod:`rigctl.runservice.queue`)."""
        start = None
        abort = False
        with self._lock:
            q = self._queue
            try:
                if kind == "queue_add":
                    q.add(payload)
                elif kind == "queue_remove":
                    q.remove(int(payload))
                elif kind == "queue_move":
                    q.move(int(payload[0]), int(payload[1]))
                elif kind == "queue_start":
                    if self.state.busy:
                        raise InputError("queue: a run is going; start the queue when it has ended")
                    start = q.start()
                elif kind == "queue_abort":
                    abort = q.abort(str(payload or "aborted by the operator"))
                elif kind == "queue_clear":
                    q.clear()
                else:
                    raise InputError(f"unknown queue command {kind!r}")
                problem = None
            except (InputError, TypeError, ValueError) as exc:
                problem = str(exc)
            self.state.queue = q.state()
        if problem is not None:
            self._log("warning", problem)
        elif kind in ("queue_start", "queue_abort") and self.state.queue.message:
            self._log("info" if kind == "queue_start" else "warning", self.state.queue.message)
        self._broadcast("queue", self.state.queue)
        if abort:
            self.abort(str(payload or "aborted by the operator") + " (queue aborted)")
        if start is not None:
            self.start(start)

    def _queue_finished(self, job: JobSpec, result: RunResult) -> None:
        """A queued run ended: record its status, start the next item or say why the queue stopped."""
        if job.queue_item is None:
            return
        status = str(result.outcome.status) if result.kind == "run" and result.outcome is not None \
            else result.kind
        message = "" if status == "completed" else (
            result.outcome.error or "" if result.kind == "run" and result.outcome is not None
            else result.message)
        with self._lock:
            was_running = self._queue.running
            nxt = None if self._stop.is_set() else self._queue.finished(job.queue_item, status,
                                                                         message or "")
            if self._stop.is_set():
                self._queue.abort("run service stopped")
            self.state.queue = self._queue.state()
        self._broadcast("queue", self.state.queue)
        if was_running and not self._queue.running:
            self._log("info" if status == "completed" else "warning", self.state.queue.message)
        if nxt is not None:
            self.start(nxt)

    def abort(self, reason: str) -> None:
        if self._controls is not None and self.state.busy:
            self._controls.abort(reason)
            self._controls.resume()

    def emergency_stop(self, reason: str) -> None:
        """The drivers' latched emergency stop (every registered stage stopped, motion refused until
        reset), from any state; a run is aborted (its safe state cannot move while latched)."""
        self.abort(reason)  # first: the step then sees the abort, not only the e-stop's stage alarm
        problems = []
        registries: list[Any] = []
        for stage in (self.rig.devices.tangential_stage, self.rig.devices.normal_stage):
            reg = stage.emergency_stop_registry
            if all(reg is not r for r in registries):
                registries.append(reg)
        for reg in registries:
            problems += [f"{f.stage_name}: {f.error}" for f in reg.trigger(reason)]
        self._log("error", f"EMERGENCY STOP ({reason})" + (f"; failed: {'; '.join(problems)}"
                                                          if problems else ""))

    def devices_snapshot(self) -> RigSnapshot:
        readings: dict[str, float] = {}
        runner = self._runner
        if self.state.busy and runner is not None and runner.ctx is not None:
            with contextlib.suppress(Exception):
                readings = {k: float(v) for k, v in runner.ctx.acq.latest().items()}
        return snapshot(self.rig, readings, self.state.busy)

    def jog(self, axis: str, delta_m: float, velocity_m_s: float) -> tuple[bool, str]:
        """A jog between runs; (False, why) if refused (a run going, a limit, the e-stop)."""
        if self.state.busy:
            return False, "jog refused: a run is going (pause does not free the stages)"
        try:
            jog(self.rig, axis, delta_m, velocity_m_s)
        except Exception as exc:
            return False, f"jog refused: {exc}"
        return True, f"{axis}: moving by {delta_m * 1e6:+.1f} um at {velocity_m_s * 1e6:.1f} um/s"

    def reset_emergency_stop(self) -> None:
        problems = reset_emergency_stop(self.rig)
        self._log("warning" if problems else "info",
                  "emergency stop reset: motion commands accepted again"
                  + (f"; alarm reset failed: {'; '.join(problems)}" if problems else ""))

    def start(self, job: JobSpec) -> None:
        with self._lock:
            if self.state.busy:
                link_msg = "a run is already going; not started"
                busy = True
            else:
                busy = False
                self.state.busy = True
                self.state.job = job
                self.state.plan = None
                self.state.progress = None
                self.state.paused = False
                self.state.run_path = None if job.dry else job.out
                self._controls = Controls()
        if busy:
            self._log("warning", link_msg)
            if job.queue_item is not None:
                self._queue_finished(job, RunResult("error", link_msg))
            return
        self._broadcast("state", self.state)
        self._broadcast("started", job)
        self._thread = threading.Thread(target=self._work, args=(job,), name="runservice-run",
                                        daemon=False)
        self._thread.start()

    # ------------------------------------------------------------------ the run (worker thread)
    def _work(self, job: JobSpec) -> None:
        result = RunResult("error", "nothing done")
        try:
            runner = self._build(job)
            try:
                plan, _ = runner.plan()
            except PlanError as exc:
                result = RunResult("refused", f"dry run refused: {exc}",
                                   culprits=self._culprits(runner, str(exc)))
                return
            self.state.plan = plan
            self._broadcast("planned", plan)
            if job.dry:
                result = RunResult("dry", "dry run: nothing moved")
                return
            outcome = runner.run()
            result = RunResult("run", str(outcome.status), outcome)
        except PlanError as exc:
            result = RunResult("refused", f"refused: {exc}")
        except Exception as exc:
            result = RunResult("error", f"{type(exc).__name__}: {exc}")
        finally:
            with self._lock:
                self.state.busy = False
                self.state.paused = False
                self._idle_since = time.monotonic()
            self._join_forwarders()
            if result.kind == "run" and result.outcome is not None:
                self._log("info", f"run {result.outcome.status}: {result.outcome.path}")
            self._broadcast("done", result)
            self._queue_finished(job, result)

    def _join_forwarders(self) -> None:
        """Wait for the run's live forwarders to flush their last DAQ block and camera frame, so
        that they reach every client before the run's ``done`` (one ordered queue per client): a
        queued run starts right after ``done``, and a window resets its live view there. A
        forwarder still going after FORWARD_JOIN_S is left (it only sends)."""
        forwarders, self._forwarders = self._forwarders, []
        deadline = time.monotonic() + FORWARD_JOIN_S
        for thread in forwarders:
            thread.join(max(0.0, deadline - time.monotonic()))
            if thread.is_alive():
                _log.warning("live forwarder %s still going after %.0f s; the run's done is sent",
                             thread.name, FORWARD_JOIN_S)

    def _culprits(self, runner: Runner, refusal: str) -> tuple[str, ...]:
        try:
            x0 = runner.devices.tangential_stage.position_m()
            return refusal_culprits(runner.protocol, runner.params, runner.limits, x0, refusal)
        except Exception:  # the attribution is a help; the refusal itself stands
            return ()

    def _build(self, job: JobSpec) -> Runner:
        rig = self.rig
        protocol = get_protocol(job.protocol)
        given = parse_assignments([f"{k}={v}" for k, v in job.given.items()])
        controls = self._controls
        assert controls is not None

        def on_acquisition(acq: Acquisition) -> None:
            sub = acq.publisher.subscribe("daq", maxlen=512)
            live = threading.Thread(target=self._forward, args=(sub, acq),
                                    name="runservice-live", daemon=True)
            live.start()
            self._forwarders.append(live)
            if acq.record_camera:
                self._forwarders.append(start_forwarding(
                    acq.publisher.subscribe("camera", maxlen=120),
                    lambda frame: self._broadcast("frame", frame), lambda: self.state.busy,
                    name="runservice-frames"))

        def progress(i: int, n: int, desc: str, elapsed: float, eta: float) -> None:
            ctx = runner.ctx
            p = (i, n, desc, elapsed, eta, ctx.acq.t_s if ctx else math.nan)
            self.state.progress = p
            self._broadcast("progress", p)

        runner = rig.runner(  # built as rigctl run builds it (rigctl/rigs.py)
            protocol, given, out=None if job.dry or job.out is None else Path(job.out),
            camera=job.camera, operator=job.operator, notes=job.notes,
            metadata={"started_from": job.started_from, "run_service_pid": str(os.getpid())},
            controls=controls, progress=progress, overwrite=job.overwrite,
            on_acquisition=on_acquisition,
        )
        self._runner = runner
        return runner

    def _forward(self, sub: Any, acq: Acquisition | None = None) -> None:
        """Live DAQ blocks to every client (the columns the live view needs), until the run ends;
        a ``dropped data`` warning when one of the acquisition's drop counters grows."""
        seen: dict[str, int] = {}
        next_check_s = time.monotonic() + DROP_CHECK_INTERVAL_S
        while self.state.busy or not sub.closed:
            if acq is not None and time.monotonic() >= next_check_s:
                next_check_s = time.monotonic() + DROP_CHECK_INTERVAL_S
                for level, text in drop_events(acq.stats, seen):
                    self._log(level, text)
            block = sub.get(timeout_s=0.2)
            if block is None:
                if not self.state.busy:
                    return
                continue
            self._broadcast("daq", {k: block[k] for k in LIVE_COLUMNS if k in block})


def service_alive(address: Address, timeout_s: float = 2.0) -> bool:
    """True if a run service answers on ``address``."""
    if not Path(address.socket).exists() or not address.key_file.exists():
        return False
    try:
        conn = Client(address.socket, family="AF_UNIX", authkey=address.key())
    except (OSError, EOFError, ValueError, Exception):
        return False
    try:
        return bool(conn.poll(timeout_s))
    finally:
        conn.close()


def main(argv: list[str] | None = None) -> int:
    from rigctl.config.loader import load_effective_config
    from rigctl.errors import InputError
    from rigctl.rigs import parse_speed
    from rigctl.runservice.wire import default_address

    parser = argparse.ArgumentParser(prog="python -m rigctl.runservice",
                                     description="the run service of rigctl gui (owns the rig)")
    parser.add_argument("--backend", default=None, choices=["sim", "sim-wire", "real"])
    parser.add_argument("--config", default=None)
    parser.add_argument("--speed", default="1")
    parser.add_argument("--dir", default=None, help="runtime folder (socket, key, log)")
    parser.add_argument("--idle-exit-s", type=float, default=10.0)
    parser.add_argument("--orphan", choices=["continue", "abort"], default="continue",
                        help="a run whose last client went away: goes on (default) or is aborted")
    parser.add_argument("--orphan-grace-s", type=float, default=5.0)
    args = parser.parse_args(argv)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # a closed terminal never ends the service
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    try:
        speed = parse_speed(args.speed)
        config, source = load_effective_config(args.config)
    except InputError as exc:
        print(f"rigctl runservice: error: {exc}", file=sys.stderr)
        return 2
    backend = args.backend or config.rig.backend
    if backend == "real" and source is None:
        print("rigctl runservice: error: the real backend needs a rig configuration: --config rig.toml",
              file=sys.stderr)
        return 2
    address = Address(Path(args.dir)) if args.dir else default_address()
    try:  # before the rig opens: a folder others may write is refused (runservice/private.py)
        address.directory.mkdir(parents=True, exist_ok=True, mode=0o700)
        check_private_folder(address.directory)
    except (OSError, ServiceFolderError) as exc:
        print(f"rigctl runservice: error: {exc}", file=sys.stderr)
        return 2
    if service_alive(address):
        print(f"rigctl runservice: error: a run service is already listening on {address.socket}",
              file=sys.stderr)
        return 1
    return serve(backend, config, speed, address, speed_text=args.speed, idle_exit_s=args.idle_exit_s,
                 orphan=args.orphan, orphan_grace_s=args.orphan_grace_s)


def serve(backend: str, config: RigConfig, speed: float, address: Address, **kw: Any) -> int:
    with open_rig(backend, config, speed) as rig:
        service = RunService(rig, backend, address, **kw)
        WarningForwarder(lambda level, text: service._broadcast("log", (level, text))).install()

        def on_signal(signum: int, frame: FrameType | None) -> None:
            service.stop(f"run service terminated (signal {signum})")

        for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGQUIT):
            signal.signal(signum, on_signal)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)  # the terminal of the GUI that started it closing
        service.serve()
    return 0
