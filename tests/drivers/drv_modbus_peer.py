"""A scripted Modbus TCP peer for conversation tests: records every request, byte for byte.

It answers FC03 (read holding registers), FC06 (write single) and FC16 (write multiple) from a
plain register list, and can be told to go silent, answer garbage, or drop the connection. It binds
127.0.0.1 port 0 and runs one thread; ``close()`` stops it.
"""

from __future__ import annotations

import socket
import struct
import threading
from dataclasses import dataclass


@dataclass(frozen=True)
class Request:
    """One request as seen on the wire: unit id, function code, PDU data after the code."""

    unit: int
    function: int
    data: bytes

    @property
    def address(self) -> int:
        return int(struct.unpack(">H", self.data[:2])[0])


class ModbusPeer:
    def __init__(self, n_registers: int = 16) -> None:
        self.registers = [0] * n_registers
        self.requests: list[Request] = []
        self.mode = "normal"  # normal | silent | garbage | drop | exception | raw
        self.raw_reply = b""  # sent as-is in mode "raw"
        self.drops_left = 0  # in mode "normal": drop this many connections on their first request
        self.exception_code = 2
        self.on_write: list = []  # callables(address, values) run after each write
        self.connections = 0
        self._lock = threading.Lock()
        self._server = socket.create_server(("127.0.0.1", 0))
        self._server.settimeout(0.05)
        self.port = self._server.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    # helpers -----------------------------------------------------------------------------------
    def set_int32(self, address: int, value: int, high_first: bool = True) -> None:
        raw = value & 0xFFFFFFFF
        words = [raw >> 16, raw & 0xFFFF]
        if not high_first:
            words.reverse()
        self.registers[address : address + 2] = words

    def writes(self) -> list[tuple[int, bytes]]:
        """(function, data) of every write request, in order."""
        return [(r.function, r.data) for r in self.requests if r.function in (6, 16)]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self._server.close()

    # server ------------------------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            self.connections += 1
            with conn:
                conn.settimeout(0.05)
                self._handle(conn)

    def _handle(self, conn: socket.socket) -> None:
        buf = b""
        while not self._stop.is_set():
            try:
                chunk = conn.recv(512)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                return
            buf += chunk
            while len(buf) >= 7:
                tid, _proto, length, unit = struct.unpack(">HHHB", buf[:7])
                if len(buf) < 6 + length:
                    break
                pdu, buf = buf[7 : 6 + length], buf[6 + length :]
                request = Request(unit, pdu[0], pdu[1:])
                with self._lock:
                    self.requests.append(request)
                if self.mode == "silent":
                    continue
                if self.mode == "drop":
                    return
                if self.drops_left > 0:
                    self.drops_left -= 1
                    return
                if self.mode == "raw":
                    conn.sendall(self.raw_reply)
                    continue
                if self.mode == "garbage":
                    conn.sendall(b"\x13\x37garbage!")
                    continue
                reply = self._reply(request)
                conn.sendall(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)

    def _reply(self, req: Request) -> bytes:
        if self.mode == "exception":
            return bytes([req.function | 0x80, self.exception_code])
        if req.function == 3:
            address, count = struct.unpack(">HH", req.data[:4])
            words = self.registers[address : address + count]
            return bytes([3, 2 * count]) + struct.pack(f">{count}H", *words)
        if req.function == 6:
            address, value = struct.unpack(">HH", req.data[:4])
            self.registers[address] = value
            for hook in self.on_write:
                hook(address, [value])
            return bytes([6]) + req.data[:4]
        if req.function == 16:
            address, count, _nbytes = struct.unpack(">HHB", req.data[:5])
            values = list(struct.unpack(f">{count}H", req.data[5 : 5 + 2 * count]))
            self.registers[address : address + count] = values
            for hook in self.on_write:
                hook(address, values)
            return bytes([16]) + req.data[:4]
        return bytes([req.function | 0x80, 1])
