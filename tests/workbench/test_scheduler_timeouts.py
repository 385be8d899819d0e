"""A Dask scheduler address whose port accepts but never answers: connect is refused in one line
naming the scheduler within its time limit (issue 35 item 10; before, the command hung without a
word: ``distributed.Client(timeout=)`` does not bound the handshake after the TCP connection)."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest

from rigctl.workbench.parallel import SchedulerError, connect


@pytest.fixture
def silent_port() -> Iterator[int]:
    """A port on 127.0.0.1 that accepts connections and never sends a byte."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.1)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])
            except TimeoutError:
                continue
            except OSError:
                return

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield server.getsockname()[1]
    stop.set()
    thread.join(5)
    for conn in held:
        conn.close()
    server.close()


def test_a_scheduler_that_never_answers_is_named_within_the_time_limit(silent_port: int) -> None:
    address = f"tcp://127.0.0.1:{silent_port}"
    result: list[BaseException | None] = []

    def attempt() -> None:
        try:
            connect(address, timeout_s=1.0)
            result.append(None)
        except BaseException as exc:  # what it raised is what the test checks
            result.append(exc)

    t0 = time.monotonic()
    thread = threading.Thread(target=attempt, daemon=True)  # a hang fails the test, not the run
    thread.start()
    thread.join(20.0)
    assert result, "connect hung on a port that never answers"
    assert time.monotonic() - t0 < 10.0
    exc = result[0]
    assert isinstance(exc, SchedulerError), exc
    assert str(exc) == (f"the Dask scheduler at {address} did not answer within 1 s (is it a Dask "
                        "scheduler, and is it running?)")


def test_a_closed_port_is_named_at_once() -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    with pytest.raises(SchedulerError, match=f"at tcp://127.0.0.1:{port}"):
        connect(f"tcp://127.0.0.1:{port}", timeout_s=1.0)
