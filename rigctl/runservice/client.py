"""The GUI's side of the run service: start it (detached) if none is listening, connect, talk.

Messages from the service arrive in a reader thread and are handed to ``on_message(kind, payload)``
(the GUI turns them into queued Qt signals); ``("lost", None)`` is delivered once if the connection
ends.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Client, Connection
from typing import Any

from rigctl.errors import DeviceError
from rigctl.runservice.private import ServiceFolderError, check_private_folder
from rigctl.runservice.server import service_alive
from rigctl.runservice.wire import Address, default_address

START_TIMEOUT_S = 90.0
"""Wall time a new service may take to open the rig and listen (imports, numba cache)."""


class ServiceStartError(DeviceError):
    """The run service could not be started or reached."""

    def __init__(self, message: str) -> None:
        super().__init__("run service", message)


def spawn_service(address: Address, backend: str, speed_text: str, config_path: str | None = None,
                  extra: list[str] | None = None) -> subprocess.Popen[bytes]:
    """Start ``python -m rigctl.runservice`` in a new session (a signal to our group does not reach it)."""
    address.directory.mkdir(parents=True, exist_ok=True, mode=0o700)
    try:
        check_private_folder(address.directory)  # said here, not only in the service's log
    except ServiceFolderError as exc:
        raise ServiceStartError(str(exc)) from None
    cmd = [sys.executable, "-m", "rigctl.runservice", "--backend", backend, "--speed", speed_text,
           "--dir", str(address.directory), *(extra or [])]
    if config_path:
        cmd += ["--config", config_path]
    log = open(address.log_file, "ab")  # noqa: SIM115 - handed to the child, closed below
    try:
        return subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True, close_fds=True)
    finally:
        log.close()


class ServiceClient:
    """A connection to a run service."""

    def __init__(self, conn: Connection, on_message: Callable[[str, Any], None]) -> None:
        self._conn = conn
        self._on_message = on_message
        self._send_lock = threading.Lock()
        self.connected = True
        self._reader = threading.Thread(target=self._read_loop, name="runservice-client", daemon=True)
        self._reader.start()

    @classmethod
    def connect(cls, address: Address, on_message: Callable[[str, Any], None]) -> ServiceClient:
        conn = Client(address.socket, family="AF_UNIX", authkey=address.key())
        return cls(conn, on_message)

    @classmethod
    def ensure(cls, on_message: Callable[[str, Any], None], *, backend: str, speed_text: str,
               config_path: str | None = None, address: Address | None = None,
               extra: list[str] | None = None, timeout_s: float = START_TIMEOUT_S) -> ServiceClient:
        """Connect to the service on ``address``, starting one first if none answers."""
        address = address or default_address()
        if not service_alive(address):
            proc = spawn_service(address, backend, speed_text, config_path, extra)
            deadline = time.monotonic() + timeout_s
            while not service_alive(address, timeout_s=1.0):
                if proc.poll() is not None:
                    raise ServiceStartError(
                        f"the run service exited with code {proc.returncode} before listening "
                        f"(see {address.log_file})")
                if time.monotonic() > deadline:
                    raise ServiceStartError(f"the run service did not listen on {address.socket} "
                                            f"within {timeout_s:.0f} s (see {address.log_file})")
                time.sleep(0.1)
        return cls.connect(address, on_message)

    def send(self, kind: str, payload: Any = None) -> bool:
        """Send a command; False if the service is gone."""
        with self._send_lock:
            try:
                self._conn.send((kind, payload))
                return True
            except (OSError, EOFError, ValueError):
                return False

    def _read_loop(self) -> None:
        try:
            while True:
                kind, payload = self._conn.recv()
                self._on_message(kind, payload)
        except (OSError, EOFError, ValueError, TypeError):
            pass
        finally:
            self.connected = False
            self._on_message("lost", None)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._conn.close()
