"""Where the run service listens and how its messages look (shared by server and client).

The service listens on a Unix-domain socket through :mod:`multiprocessing.connection` (length-prefixed
pickles, HMAC challenge with a per-service key stored next to the socket with mode 0600, so only the
user who started it can connect; the folder must be that user's alone: :mod:`.private`). Messages
are tuples ``(kind, payload)``; one that is not a known command with a payload of its kind is
answered with an error line (:mod:`.messages`), the connection kept.

Client to service: ``("start", JobSpec)``, ``("pause", None)``, ``("resume", None)``,
``("abort", reason)``, ``("estop", reason)``, ``("shutdown", None)``; the queue
(:mod:`rigctl.runservice.queue`): ``("queue_add", JobSpec)``, ``("queue_remove", item)``,
``("queue_move", (item, +1 or -1))``, ``("queue_start", None)``, ``("queue_abort", reason)``,
``("queue_clear", None)`` (pause and resume of the queue are ``pause``/``resume`` of its current run).
Service to client: ``("hello", ServiceState)``, ``("planned", Plan)``, ``("progress", (i, n, step,
elapsed, eta, device_t))``, ``("daq", columns)``, ``("frame", LiveFrame)`` (a downsampled camera
image a few times a second with every frame's Isum, :mod:`rigctl.runservice.frames`), ``("done",
RunResult)``, ``("log", (level, text))`` (the service's own lines, the run's warnings, pause/resume and
dropped data), ``("state", ServiceState)``, ``("started", JobSpec)`` (a run begins: the window sets
up its display even when the queue, not the window, started it), ``("queue", QueueState)``.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rigctl.runservice.private import read_key, write_key

RUNTIME_DIR_ENV = "RIGCTL_RUNTIME_DIR"
SOCKET_NAME = "runservice.sock"
KEY_NAME = "runservice.key"
LOG_NAME = "runservice.log"
LIVE_COLUMNS = ("t_s", "ft_N", "fn_N", "d1_m", "d2_m")
"""DAQ columns forwarded to clients for the live view."""


def runtime_dir() -> Path:
    """``$RIGCTL_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/rigctl``, else ``<tmp>/rigctl-<uid>``."""
    if os.environ.get(RUNTIME_DIR_ENV):
        return Path(os.environ[RUNTIME_DIR_ENV])
    if os.environ.get("XDG_RUNTIME_DIR"):
        return Path(os.environ["XDG_RUNTIME_DIR"]) / "rigctl"
    return Path(tempfile.gettempdir()) / f"rigctl-{os.getuid()}"


@dataclass(frozen=True)
class Address:
    directory: Path

    @property
    def socket(self) -> str:
        return str(self.directory / SOCKET_NAME)

    @property
    def key_file(self) -> Path:
        return self.directory / KEY_NAME

    @property
    def log_file(self) -> Path:
        return self.directory / LOG_NAME

    def new_key(self) -> bytes:
        """Write a fresh key (a new file, mode 0600) for a service about to listen here; the folder
        must be this user's alone to write (:mod:`rigctl.runservice.private`)."""
        self.directory.mkdir(parents=True, exist_ok=True, mode=0o700)
        return write_key(self.key_file)

    def key(self) -> bytes:
        """The service's key, read only from this user's private folder and file."""
        return read_key(self.key_file)


def default_address() -> Address:
    return Address(runtime_dir())


@dataclass(frozen=True)
class JobSpec:
    """One protocol run as the GUI asks for it (parameters as text, exactly like ``--param``)."""

    protocol: str
    given: dict[str, Any]
    out: str | None
    overwrite: bool = False
    camera: bool = True
    dry: bool = False
    operator: str | None = None
    notes: str = ""
    speed_text: str = "1"
    started_from: str = "gui"
    queue_item: int | None = None
    """The queue item this run is (None for a run started on its own)."""


@dataclass(frozen=True)
class RunResult:
    kind: str
    """'dry' (plan shown), 'refused' (plan error), 'run' (outcome), 'error' (nothing recorded)."""
    message: str = ""
    outcome: Any = None
    """experiments.runner.RunOutcome for kind 'run'."""
    culprits: tuple[str, ...] = ()
    """For kind 'refused': the edited parameters whose default value would pass the plan."""


@dataclass
class ServiceState:
    backend: str
    speed: float
    rig: str
    pid: int
    busy: bool = False
    job: JobSpec | None = None
    plan: Any = None
    progress: tuple[int, int, str, float, float, float] | None = None
    run_path: str | None = None
    paused: bool = False
    log: list[tuple[str, str]] = field(default_factory=list)
    queue: Any = None
    """rigctl.runservice.queue.QueueState: the queued runs and their status."""
