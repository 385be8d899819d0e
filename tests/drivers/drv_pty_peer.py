"""A scripted serial peer behind a pty pair: the driver opens the slave path like a real port."""

from __future__ import annotations

import os
import select
import threading
import tty
from collections.abc import Callable


class PtyPeer:
    """Reads CR-terminated commands on the master side and answers from ``replies``.

    ``replies`` maps a command line (without CR) to the reply lines to send (without CR); a
    callable ``handler`` can be given instead. ``silent`` suppresses all answers.
    """

    def __init__(self, replies: dict[bytes, list[bytes]] | None = None) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.replies = dict(replies or {})
        self.handler: Callable[[bytes], list[bytes]] | None = None
        self.received: list[bytes] = []
        self.silent = False
        self.overlaps = 0  # commands that arrived before the previous one was answered
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            try:
                buffer += os.read(self.master, 1024)
            except OSError:
                return
            while b"\r" in buffer:
                line, buffer = buffer.split(b"\r", 1)
                self.received.append(line)
                if self.silent:
                    continue
                answer = self.handler(line) if self.handler else self.replies.get(line, [])
                if b"\r" in buffer or select.select([self.master], [], [], 0)[0]:
                    self.overlaps += 1
                for reply in answer:
                    self.send_raw(reply + b"\r")

    def send_raw(self, data: bytes) -> None:
        with self._lock:
            os.write(self.master, data)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self.master)
        os.close(self.slave)


class RtuPeer:
    """A Modbus RTU responder behind a pty: 8-byte requests (FC03/FC06) in, ``answer(req)`` out."""

    def __init__(self, answer: Callable[[bytes], bytes]) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.requests: list[bytes] = []
        self._answer = answer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            buffer += os.read(self.master, 256)
            while len(buffer) >= 8:
                request, buffer = buffer[:8], buffer[8:]
                self.requests.append(request)
                os.write(self.master, self._answer(request))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self.master)
        os.close(self.slave)
