"""SerialProbe over a pty pair: the exact lines per call, replies, errors, streaming, timeouts."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.errors import (
    BadParameter,
    DeviceBusy,
    DeviceStateError,
    DeviceTimeout,
    InvalidValueError,
    OverRangeError,
    ProtocolError,
    UnknownCommand,
)
from drivers.serial_probe import ProbeConfig, SerialProbe

from .contract import ProbeContract
from .drv_pty_peer import PtyPeer

SCRIPT = {
    b"ID": [b"ID,MTI-2100,SN0042"],
    b"RG": [b"RG,74.0000,0.0190"],
    b"MS": [b"MS,+0012.3450"],
    b"ZR": [b"ZR"],
    b"ST,1024": [b"ST"],
    b"SP": [b"SP"],
}


@pytest.fixture
def rig() -> Iterator[tuple[SerialProbe, PtyPeer]]:
    peer = PtyPeer(SCRIPT)
    probe = SerialProbe(ProbeConfig(name="probe1", url=peer.path))
    yield probe, peer
    probe.close()
    peer.close()


def test_identify_range_measure_zero_conversation(rig: tuple[SerialProbe, PtyPeer]) -> None:
    probe, peer = rig
    assert probe.identify() == ("MTI-2100", "SN0042")
    assert probe.range_m == pytest.approx(74e-6)
    assert probe.resolution_m == pytest.approx(0.019e-6)
    assert probe.range_m == pytest.approx(74e-6)  # cached: asked once
    assert probe.read_m() == pytest.approx(12.345e-6)
    probe.zero()
    assert peer.received == [b"ID", b"RG", b"MS", b"ZR"]


def test_negative_value(rig: tuple[SerialProbe, PtyPeer]) -> None:
    probe, peer = rig
    peer.replies[b"MS"] = [b"MS,-0036.9990"]
    assert probe.read_m() == pytest.approx(-36.999e-6)


@pytest.mark.parametrize(("reply", "direction"), [(b"MS,+OVER", 1), (b"MS,-OVER", -1)])
def test_over_range_raises_never_clips(
    rig: tuple[SerialProbe, PtyPeer], reply: bytes, direction: int
) -> None:
    probe, peer = rig
    peer.replies[b"MS"] = [reply]
    with pytest.raises(OverRangeError) as info:
        probe.read_m()
    assert info.value.direction == direction


@pytest.mark.parametrize(
    ("code", "error"), [(b"01", UnknownCommand), (b"02", BadParameter), (b"03", DeviceBusy)]
)
def test_error_replies_are_named(
    rig: tuple[SerialProbe, PtyPeer], code: bytes, error: type[Exception]
) -> None:
    probe, peer = rig
    peer.replies[b"ZR"] = [b"ER,ZR," + code]
    with pytest.raises(error, match="ZR"):
        probe.zero()


@pytest.mark.parametrize("reply", [b"MS,12.345", b"MS", b"XX,+0001.0000", b"MS,+0001.00\xff0"])
def test_malformed_replies_are_protocol_errors(rig: tuple[SerialProbe, PtyPeer], reply: bytes) -> None:
    probe, peer = rig
    peer.replies[b"MS"] = [reply]
    with pytest.raises(ProtocolError) as info:
        probe.read_m()
    assert info.value.data == reply


def test_silent_probe_times_out_within_one_second(rig: tuple[SerialProbe, PtyPeer]) -> None:
    probe, peer = rig
    peer.silent = True
    started = time.monotonic()
    with pytest.raises(DeviceTimeout, match=r"probe1 did not answer within 0\.6 s"):
        probe.read_m()
    assert time.monotonic() - started < 1.0
    assert peer.received == [b"MS", b"MS"]


def test_one_command_in_flight_across_threads(rig: tuple[SerialProbe, PtyPeer]) -> None:
    probe, peer = rig

    def slow(line: bytes) -> list[bytes]:
        time.sleep(0.003)  # a second command written meanwhile would be seen as an overlap
        return SCRIPT[line]

    peer.handler = slow
    values: list[float] = []

    def reader() -> None:
        for _ in range(10):
            values.append(probe.read_m())

    threads = [threading.Thread(target=reader) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=5)
    assert values == [pytest.approx(12.345e-6)] * 30
    assert len(peer.received) == 30 and peer.overlaps == 0


def test_stream_with_sequence_gap_over_range_and_bad_line(
    rig: tuple[SerialProbe, PtyPeer],
) -> None:
    probe, peer = rig
    probe.start_stream(1024)
    assert peer.received == [b"ST,1024"]
    peer.send_raw(b"D,0,+0001.0000\rD,1,-0002.5000\rD,4,+OVER\rD,x,+0001.0000\rD,5,-OVER\rD,6,+0000.0190\r")
    seq, values, host_ns = probe.read_stream(100, timeout_s=0.5)
    while len(seq) < 5:
        more = probe.read_stream(100, timeout_s=0.5)
        seq = np.concatenate([seq, more.seq])
        values = np.concatenate([values, more.values_m])
        host_ns = np.concatenate([host_ns, more.host_ns])
    assert seq.tolist() == [0, 1, 4, 5, 6]
    assert values[0] == pytest.approx(1e-6) and values[1] == pytest.approx(-2.5e-6)
    assert values[2] == math.inf and values[3] == -math.inf
    assert values[4] == pytest.approx(0.019e-6)
    assert probe.dropped_samples == 2  # seq 2 and 3 never came
    assert probe.protocol_errors == 1
    assert probe.last_protocol_error is not None
    assert probe.last_protocol_error.data == b"D,x,+0001.0000"
    assert np.all(np.diff(host_ns) >= 0)
    with pytest.raises(DeviceStateError):
        probe.read_m()  # one reading while streaming is refused before sending
    probe.stop_stream()
    assert peer.received == [b"ST,1024", b"SP"]


def test_silent_stream_raises_device_timeout(rig: tuple[SerialProbe, PtyPeer]) -> None:
    probe, _ = rig
    probe.start_stream(1024)
    started = time.monotonic()
    with pytest.raises(DeviceTimeout, match="no stream lines"):
        for _ in range(20):
            probe.read_stream(10, timeout_s=0.1)
    assert time.monotonic() - started < 1.0


@pytest.mark.parametrize("rate", [float("nan"), 0.0, -5.0, 10.5, "fast"])
def test_bad_stream_rates_refused_before_sending(rig: tuple[SerialProbe, PtyPeer], rate: object) -> None:
    probe, peer = rig
    with pytest.raises(InvalidValueError):
        probe.start_stream(rate)  # type: ignore[arg-type]
    time.sleep(0.03)
    assert peer.received == []
    assert not probe.streaming


def test_socket_url_works(rig: tuple[SerialProbe, PtyPeer]) -> None:
    import socket

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def serve() -> None:
        conn, _ = server.accept()
        with conn:
            data = b""
            while not data.endswith(b"\r"):
                data += conn.recv(64)
            conn.sendall(b"MS,-0000.0190\r")
            conn.recv(64)  # wait until the client closes

    worker = threading.Thread(target=serve)
    worker.start()
    try:
        with SerialProbe(ProbeConfig(name="sock", url=f"socket://127.0.0.1:{port}")) as probe:
            assert probe.read_m() == pytest.approx(-0.019e-6)
    finally:
        worker.join(timeout=2)
        server.close()


class StreamingProbePeer(PtyPeer):
    """Answers the script and streams ``D`` lines (a slow sine, one over-range) after ``ST``."""

    def __init__(self) -> None:
        super().__init__(SCRIPT)
        self.handler = self._handle
        self._streaming = threading.Event()
        self._streamer: threading.Thread | None = None

    def _handle(self, line: bytes) -> list[bytes]:
        if line.startswith(b"ST,"):
            self._streaming.set()
            self._streamer = threading.Thread(target=self._stream, daemon=True)
            self._streamer.start()
            return [b"ST"]
        if line == b"SP":
            self._streaming.clear()
            if self._streamer is not None:
                self._streamer.join(timeout=2)
            return [b"SP"]
        return SCRIPT.get(line, [b"ER," + line[:2] + b",01"])

    def _stream(self) -> None:
        n = 0
        while self._streaming.is_set():
            value = "+OVER" if n == 5 else f"{20 * math.sin(n / 50):+010.4f}"
            self.send_raw(f"D,{n},{value}\r".encode())
            n += 1
            time.sleep(0.001)

    def close(self) -> None:
        self._streaming.clear()
        if self._streamer is not None:
            self._streamer.join(timeout=2)
        super().close()


class TestSerialProbeContract(ProbeContract):
    @pytest.fixture
    def probe(self) -> Iterator[SerialProbe]:
        peer = StreamingProbePeer()
        probe = SerialProbe(ProbeConfig(name="probe1", url=peer.path))
        yield probe
        probe.close()
        peer.close()
