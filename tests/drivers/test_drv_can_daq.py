"""CanDaq: the exact command frames, replies, and what the data stream turns into (or loses)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.can_daq import DEFAULT_FORCE_N_PER_COUNT as S
from drivers.can_daq import CanDaq, CanDaqConfig
from drivers.can_frames import pack_data
from drivers.errors import (
    BadParameter,
    DeviceBusy,
    DeviceStateError,
    DeviceTimeout,
    InvalidValueError,
    LimitError,
    ProtocolError,
)
from drivers.interfaces import ChannelMap

from .contract import DaqContract
from .drv_can_peer import CanPeer, fresh_channel

CMD = 0x601


@pytest.fixture
def rig() -> Iterator[tuple[CanDaq, CanPeer]]:
    channel = fresh_channel()
    peer = CanPeer(channel)
    daq = CanDaq(CanDaqConfig(channel=channel))
    yield daq, peer
    daq.close()
    peer.close()


def read_all(daq: CanDaq, expected: int, timeout_s: float = 2.0) -> list:
    """Read blocks until ``expected`` samples came (or the time is up)."""
    blocks, got = [], 0
    deadline = time.monotonic() + timeout_s
    while got < expected and time.monotonic() < deadline:
        block = daq.read_block(expected - got, timeout_s=0.1)
        if len(block):
            blocks.append(block)
            got += len(block)
    return blocks


def cat(blocks: list, key: str) -> np.ndarray:
    return np.concatenate([getattr(b, key) for b in blocks])


# commands ------------------------------------------------------------------------------------


def test_command_frames_are_exact(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.set_rate(2048)
    daq.tare()
    daq.start()
    daq.stop()
    assert peer.commands == [
        (CMD, bytes([0x04, 0x00, 0x08])),
        (CMD, bytes([0x03])),
        (CMD, bytes([0x01])),
        (CMD, bytes([0x02])),
    ]
    assert daq.rate_hz == 2048.0


def test_status_reply_decoded(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    peer.streaming, peer.rate_hz = True, 512
    status = daq.device_status()
    assert (status.streaming, status.rate_hz) == (True, 512)
    assert peer.commands == [(CMD, bytes([0x05]))]


@pytest.mark.parametrize(("code", "error"), [(2, BadParameter), (3, DeviceBusy)])
def test_error_status_raises_named_error(
    rig: tuple[CanDaq, CanPeer], code: int, error: type[Exception]
) -> None:
    daq, peer = rig
    peer.status = code
    with pytest.raises(error) as info:
        daq.set_rate(4096)
    assert info.value.code == code  # type: ignore[attr-defined]
    assert daq.rate_hz == 1024.0  # unchanged after a refusal


def test_silent_node_times_out_within_one_second(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    peer.silent = True
    started = time.monotonic()
    with pytest.raises(DeviceTimeout, match=r"daq did not answer within 0\.6 s"):
        daq.start()
    assert time.monotonic() - started < 1.0
    assert peer.commands == [(CMD, b"\x01"), (CMD, b"\x01")]  # sent, then retried once
    assert not daq.streaming


def test_malformed_reply_is_a_protocol_error(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    peer.raw_reply = b"\x81"
    with pytest.raises(ProtocolError) as info:
        daq.start()
    assert info.value.data == b"\x81"


@pytest.mark.parametrize(
    ("rate", "error"),
    [
        (1024.5, InvalidValueError),
        (70_000, LimitError),
        (float("nan"), InvalidValueError),
        (0, InvalidValueError),
    ],
)
def test_bad_rates_refused_before_sending(
    rig: tuple[CanDaq, CanPeer], rate: float, error: type[Exception]
) -> None:
    daq, peer = rig
    with pytest.raises(error):
        daq.set_rate(rate)
    time.sleep(0.05)
    assert peer.commands == []


def test_set_rate_refused_while_streaming(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    with pytest.raises(DeviceStateError):
        daq.set_rate(2048)
    assert peer.commands == [(CMD, b"\x01")]


# data stream ---------------------------------------------------------------------------------


def test_samples_scaled_and_timed_from_the_counter(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    for n in range(100, 110):
        peer.send_sample(n, (n, -2 * n, 15_000), (16_384, -100, n))
    blocks = read_all(daq, 10)
    counter = cat(blocks, "counter")
    assert counter.tolist() == list(range(100, 110))
    np.testing.assert_allclose(cat(blocks, "t_s"), np.arange(10) / 1024.0)
    np.testing.assert_allclose(cat(blocks, "fx_N"), S * np.arange(100, 110))
    np.testing.assert_allclose(cat(blocks, "fy_N"), -2 * S * np.arange(100, 110))
    np.testing.assert_allclose(cat(blocks, "fz_N"), S * 15_000)
    ain = np.concatenate([b.ain_V for b in blocks])
    np.testing.assert_allclose(ain[:, 0], 5.0)
    assert blocks[-1].dropped_total == 0 and daq.dropped_samples == 0
    assert all(b.host_monotonic_ns > 0 for b in blocks)


def test_counter_unwraps_across_65536(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    for n in range(65_530, 65_542):
        peer.send_sample(n % 65_536)
    counter = cat(read_all(daq, 12), "counter")
    assert counter.tolist() == list(range(65_530, 65_542))


def test_drops_are_counted_not_invented(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    for n in range(20):
        if n in (5, 6):
            continue  # both frames lost
        peer.send_sample(n, send_analog=n != 10, send_force=n != 14)  # half samples
    blocks = read_all(daq, 16)
    counter = cat(blocks, "counter")
    assert 5 not in counter and 10 not in counter and 14 not in counter
    assert len(counter) == 16
    assert daq.dropped_samples == 4
    np.testing.assert_allclose(cat(blocks, "t_s"), counter / 1024.0)  # gaps stay gaps


def test_malformed_data_frames_are_counted_and_skipped(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    peer.send_sample(0)
    peer.send_frame(0x180, b"\x01\x00\x05")  # short
    peer.send_sample(1)
    counter = cat(read_all(daq, 2), "counter")
    assert counter.tolist() == [0, 1]
    assert daq.protocol_errors == 1
    assert daq.last_protocol_error is not None
    assert daq.last_protocol_error.data == b"\x01\x00\x05"


def test_silent_stream_raises_device_timeout(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    peer.send_sample(0)
    assert len(daq.read_block(10, timeout_s=0.5)) == 1
    started = time.monotonic()
    with pytest.raises(DeviceTimeout, match="no data frames"):
        for _ in range(50):
            daq.read_block(10, timeout_s=0.1)
    assert time.monotonic() - started < 1.0


def test_read_times_out_with_an_empty_block_when_not_streaming(
    rig: tuple[CanDaq, CanPeer],
) -> None:
    daq, _ = rig
    started = time.monotonic()
    block = daq.read_block(10, timeout_s=0.05)
    assert len(block) == 0 and 0.04 < time.monotonic() - started < 0.5


def test_ring_overflow_loses_oldest_and_counts_it() -> None:
    channel = fresh_channel()
    peer = CanPeer(channel)
    daq = CanDaq(CanDaqConfig(channel=channel, rx_queue_size=32))
    try:
        daq.start()
        for n in range(200):  # nobody reads: the bounded queues must drop
            peer.send_sample(n)
        time.sleep(0.1)
        daq.stop()  # frames already received stay readable
        counter = cat(read_all(daq, 200, timeout_s=0.3), "counter")
        assert 0 < len(counter) <= 17
        assert np.all(np.diff(counter) > 0)
        span = int(counter[-1] - counter[0] + 1)
        assert daq.dropped_samples == span - len(counter)
        assert counter[-1] == 199  # the newest survive
    finally:
        daq.close()
        peer.close()


def test_live_1024_hz_stream_loses_nothing(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    n_samples = 307  # 0.3 s

    def stream() -> None:
        t0 = time.monotonic()
        for n in range(n_samples):
            while time.monotonic() < t0 + n / 1024.0:
                time.sleep(0.0005)
            peer.send_sample(n, (n, 0, 0), (0, 0, 0))

    sender = threading.Thread(target=stream)
    sender.start()
    blocks = read_all(daq, n_samples, timeout_s=3.0)
    sender.join()
    counter = cat(blocks, "counter")
    assert counter.tolist() == list(range(n_samples))
    assert daq.dropped_samples == 0 and daq.protocol_errors == 0
    host = np.array([b.host_monotonic_ns for b in blocks])
    assert np.all(np.diff(host) >= 0)


def test_channel_map_gives_ft_fn_d1_d2(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    peer.send_sample(0, (1000, 0, -15_000), (10_000, -5_000, 0))
    block = read_all(daq, 1)[0]
    cmap = ChannelMap(ft_axis="fx", fn_axis="fz", fn_sign=-1)
    assert cmap.ft_N(block)[0] == pytest.approx(S * 1000)
    assert cmap.fn_N(block)[0] == pytest.approx(S * 15_000)
    assert cmap.d1_m(block)[0] == pytest.approx(7.4e-6 * 10_000 * 10 / 32768)
    assert cmap.d2_m(block)[0] == pytest.approx(-7.4e-6 * 5_000 * 10 / 32768)


def test_frames_for_another_node_are_ignored(rig: tuple[CanDaq, CanPeer]) -> None:
    daq, peer = rig
    daq.start()
    peer.bus.send(
        __import__("can").Message(arbitration_id=0x182, data=pack_data(0, 1, 2, 3), is_extended_id=False)
    )
    peer.send_sample(7)
    counter = cat(read_all(daq, 1), "counter")
    assert counter.tolist() == [7] and daq.protocol_errors == 0


class TestCanDaqContract(DaqContract):
    """The shared DAQ behaviour, with a peer streaming at 1024 Hz on a virtual bus."""

    @pytest.fixture
    def daq(self) -> Iterator[CanDaq]:
        channel = fresh_channel()
        peer = CanPeer(channel)
        peer.auto_stream = True
        device = CanDaq(CanDaqConfig(channel=channel))
        yield device
        device.close()
        peer.close()
