"""A scripted DAQ node on a python-can ``virtual`` bus: records commands, answers them, sends data."""

from __future__ import annotations

import math
import struct
import threading
import time
import uuid

import can

from drivers.can_frames import pack_data


def fresh_channel() -> str:
    """A virtual-bus channel no other test uses."""
    return f"drv-test-{uuid.uuid4().hex}"


class CanPeer:
    def __init__(self, channel: str, node_id: int = 1) -> None:
        self.node_id = node_id
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.commands: list[tuple[int, bytes]] = []  # (arbitration id, payload) seen
        self.silent = False
        self.status = 0  # status byte of every reply
        self.raw_reply: bytes | None = None  # if set, sent instead of the proper reply
        self.streaming = False
        self.rate_hz = 1024
        self.auto_stream = False  # if True, START makes the peer send samples until STOP
        self._streamer: threading.Thread | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            msg = self.bus.recv(timeout=0.02)
            if msg is None or msg.arbitration_id != 0x600 + self.node_id:
                continue
            payload = bytes(msg.data)
            self.commands.append((msg.arbitration_id, payload))
            if self.silent:
                continue
            if self.raw_reply is not None:
                self._reply(self.raw_reply)
                continue
            code = payload[0]
            if code == 0x01:
                self.streaming = True
                if self.auto_stream and self._streamer is None:
                    self._streamer = threading.Thread(target=self._stream, daemon=True)
                    self._streamer.start()
            elif code == 0x02:
                self.streaming = False
                self._join_streamer()
            elif code == 0x04 and self.status == 0:
                self.rate_hz = struct.unpack_from("<H", payload, 1)[0]
            if code == 0x05:
                self._reply(struct.pack("<BBBH", 0x85, self.status, self.streaming, self.rate_hz))
            else:
                self._reply(bytes([code | 0x80, self.status]))

    def _stream(self) -> None:
        """Samples at ``rate_hz`` (a sine on fx, a ramp on ain0) while streaming."""
        t0, n = time.monotonic(), 0
        while self.streaming and not self._stop.is_set():
            due = t0 + n / self.rate_hz
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(min(delay, 0.002))
                continue
            fx = int(1000 * math.sin(2 * math.pi * n / 256))
            self.send_sample(n, (fx, 0, 15_000), (n % 30_000, 0, 0))
            n += 1

    def _join_streamer(self) -> None:
        if self._streamer is not None and self._streamer is not threading.current_thread():
            self._streamer.join(timeout=2)
        self._streamer = None

    def _reply(self, data: bytes) -> None:
        self.bus.send(can.Message(arbitration_id=0x580 + self.node_id, data=data, is_extended_id=False))

    def send_frame(self, base: int, data: bytes) -> None:
        self.bus.send(can.Message(arbitration_id=base + self.node_id, data=data, is_extended_id=False))

    def send_sample(
        self,
        counter: int,
        force: tuple[int, int, int] = (0, 0, 0),
        analog: tuple[int, int, int] = (0, 0, 0),
        *,
        send_force: bool = True,
        send_analog: bool = True,
    ) -> None:
        if send_force:
            self.send_frame(0x180, pack_data(counter, *force))
        if send_analog:
            self.send_frame(0x280, pack_data(counter, *analog))

    def close(self) -> None:
        self._stop.set()
        self.streaming = False
        self._join_streamer()
        self._thread.join(timeout=2)
        self.bus.shutdown()
