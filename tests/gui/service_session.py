"""A run service on the simulated rig for a test, with a connected client whose messages go to a
queue; the service is terminated and its folder removed however the test ends."""

from __future__ import annotations

import os
import queue
import shutil
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rigctl.runservice.client import ServiceClient, spawn_service
from rigctl.runservice.server import service_alive
from rigctl.runservice.wire import Address


@dataclass
class ServiceSession:
    client: ServiceClient
    inbox: queue.Queue[tuple[str, Any]]
    proc: subprocess.Popen[bytes]


@contextmanager
def service_session(name: str, speed: str = "10", start_timeout_s: float = 90.0
                    ) -> Iterator[ServiceSession]:
    address = Address(Path(f"/tmp/rigctl-{name}-{os.getpid()}"))
    proc = spawn_service(address, "sim", speed, extra=["--idle-exit-s", "1"])
    try:
        deadline = time.monotonic() + start_timeout_s
        while not service_alive(address):
            assert time.monotonic() < deadline and proc.poll() is None, "service did not start"
            time.sleep(0.1)
        inbox: queue.Queue[tuple[str, Any]] = queue.Queue()
        client = ServiceClient.connect(address, lambda k, p: inbox.put((k, p)))
        yield ServiceSession(client, inbox, proc)
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(30)
        shutil.rmtree(address.directory, ignore_errors=True)
