"""Property-based fuzzing of every frame/line parser: only the documented named errors come out."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.can_daq import CanDaq, CanDaqConfig
from drivers.can_frames import (
    SamplePairer,
    pack_data,
    pack_reply,
    unpack_command,
    unpack_data,
    unpack_reply,
    unwrap_counter,
)
from drivers.errors import DeviceRejected, OverRangeError, ProtocolError
from drivers.interfaces import FrameDropDetector
from drivers.modbus_codec import decode_status, int32_to_words, words_to_int32
from drivers.probe_lines import (
    check_reply,
    decode_line,
    format_value,
    parse_ack,
    parse_identity,
    parse_measurement,
    parse_range,
    parse_stream_line,
    parse_value_m,
)
from drivers.serial_probe import ProbeConfig, SerialProbe

from .drv_can_peer import fresh_channel

FAST = settings(max_examples=150, deadline=None)

# bytes that look like probe lines often enough to reach the deep branches
_tokens = st.sampled_from(
    [
        "MS",
        "RG",
        "ID",
        "ZR",
        "ST",
        "SP",
        "ER",
        "D",
        "+OVER",
        "-OVER",
        "+0012.3450",
        "-0000.0190",
        "74.0000",
        "0.0190",
        "01",
        "02",
        "03",
        "99",
        "4294967296",
        "12",
        "",
        "x",
        " ",
        "1e5",
        "nan",
    ]
)
probe_lines = st.one_of(
    st.binary(max_size=100),
    st.lists(_tokens, max_size=4).map(lambda parts: ",".join(parts).encode()),
)


# CAN ------------------------------------------------------------------------------------------


@FAST
@given(st.binary(max_size=16))
def test_can_parsers_raise_only_protocol_error(payload: bytes) -> None:
    for parse in (unpack_data, unpack_reply, unpack_command):
        try:
            parse(payload)
        except ProtocolError as exc:
            assert exc.data == payload
        except Exception as exc:  # pragma: no cover - the property under test
            pytest.fail(f"{parse.__name__}({payload!r}) raised {exc!r}")


@FAST
@given(st.integers(0, 65535), *[st.integers(-32768, 32767)] * 3)
def test_data_frame_round_trip(counter: int, a: int, b: int, c: int) -> None:
    assert unpack_data(pack_data(counter, a, b, c)) == (counter, a, b, c)


@FAST
@given(st.integers(1, 5), st.integers(0, 255), st.booleans(), st.integers(0, 65535))
def test_reply_round_trip(code: int, status: int, streaming: bool, rate: int) -> None:
    reply = unpack_reply(pack_reply(code, status, streaming=streaming, rate_hz=rate))
    assert (int(reply.command), reply.status) == (code, status)
    if code == 5:
        assert (reply.streaming, reply.rate_hz) == (streaming, rate)


@FAST
@given(st.integers(0, 10**9), st.integers(-32767, 32767))
def test_unwrap_recovers_nearby_counters(reference: int, delta: int) -> None:
    true = max(reference + delta, 0)
    assert unwrap_counter(true % 65536, reference) == true


@FAST
@given(
    start=st.integers(0, 65535),
    fates=st.lists(
        st.sampled_from(["both", "both", "both", "force", "analog", "none"]), min_size=1, max_size=300
    ),
)
def test_pairer_emits_complete_samples_and_counts_the_rest(start: int, fates: list[str]) -> None:
    pairer = SamplePairer()
    emitted = []
    for i, fate in enumerate(fates):
        raw = (start + i) % 65536
        if fate in ("both", "force"):
            sample = pairer.add(True, raw, (i, 0, 0), i)
            if sample:
                emitted.append(sample)
        if fate in ("both", "analog"):
            sample = pairer.add(False, raw, (0, 0, i), i)
            if sample:
                emitted.append(sample)
    complete = [start + i for i, fate in enumerate(fates) if fate == "both"]
    assert len(emitted) == len(complete)
    if complete:
        # the unwrapped counter starts at the first raw value seen, then runs on across wraps
        assert emitted[0].counter % 65536 == complete[0] % 65536
        shift = emitted[0].counter - complete[0]
        assert [s.counter - shift for s in emitted] == complete
        assert all(s.force[0] == s.analog[2] == s.counter - shift - start for s in emitted)
        assert pairer.dropped == (complete[-1] - complete[0] + 1) - len(complete)


@pytest.fixture(scope="module")
def daq() -> Iterator[CanDaq]:
    device = CanDaq(CanDaqConfig(channel=fresh_channel()))
    yield device
    device.close()


@settings(max_examples=100, deadline=None)
@given(frames=st.lists(st.tuples(st.booleans(), st.binary(max_size=12), st.booleans()), max_size=30))
@pytest.mark.slow
def test_can_daq_survives_any_frames(daq: CanDaq, frames: list[tuple[bool, bytes, bool]]) -> None:
    errors_before = daq.protocol_errors
    for is_force, payload, remote in frames:
        daq._listener.ring.append((is_force, payload, time.monotonic_ns(), remote))
    got = 0
    while True:
        block = daq.read_block(64, timeout_s=0)
        if not len(block):
            break
        got += len(block)
    bad = sum(1 for _, p, r in frames if r or len(p) != 8)
    assert daq.protocol_errors - errors_before == bad
    assert got <= len(frames) - bad


# Modbus ---------------------------------------------------------------------------------------


@FAST
@given(st.lists(st.integers(-(2**20), 2**20), max_size=4), st.sampled_from(["high_first", "low_first"]))
def test_int32_decoder_raises_only_protocol_error(words: list[int], order: str) -> None:
    try:
        value = words_to_int32(words, order)  # type: ignore[arg-type]
    except ProtocolError:
        return
    assert -(2**31) <= value < 2**31


@FAST
@given(st.integers(-(2**31), 2**31 - 1), st.sampled_from(["high_first", "low_first"]))
def test_int32_round_trip(value: int, order: str) -> None:
    assert words_to_int32(int32_to_words(value, order), order) == value  # type: ignore[arg-type]


@FAST
@given(st.integers(-5, 70000), st.integers(-5, 70000))
def test_status_decoder_raises_only_protocol_error(word: int, alarm: int) -> None:
    try:
        status = decode_status(word, alarm)
    except ProtocolError:
        return
    assert status.alarm_code == alarm and isinstance(status.alarm_name, str)


# probe lines ----------------------------------------------------------------------------------

ALLOWED = (ProtocolError, DeviceRejected, OverRangeError)


@FAST
@given(probe_lines)
def test_probe_parsers_raise_only_named_errors(line: bytes) -> None:
    parsers: list[Callable[[bytes], object]] = [
        decode_line,
        lambda b: check_reply(b, "MS"),
        parse_measurement,
        parse_range,
        parse_identity,
        lambda b: parse_ack(b, "ZR"),
        parse_stream_line,
    ]
    for parse in parsers:
        try:
            result = parse(line)
        except ALLOWED:
            continue
        except Exception as exc:  # pragma: no cover - the property under test
            pytest.fail(f"parser raised {exc!r} for {line!r}")
        if parse is parse_measurement:
            assert isinstance(result, float) and math.isfinite(result)
        if parse is parse_range:
            assert isinstance(result, tuple) and 0 < result[1] <= result[0]


@FAST
@given(st.floats(-999_999e-6, 999_999e-6, allow_nan=False))
def test_value_round_trip_is_quantised_to_a_tenth_nanometre(value_m: float) -> None:
    assert abs(parse_value_m(format_value(value_m)) - value_m) <= 0.5e-10 + 1e-15


@pytest.fixture(scope="module")
def probe() -> Iterator[SerialProbe]:
    device = SerialProbe(ProbeConfig(url="loop://"))
    yield device
    device.close()


@settings(max_examples=200, deadline=None)
@given(probe_lines.map(lambda b: b"D," + b))
@pytest.mark.slow
def test_probe_stream_dispatch_survives_any_line(probe: SerialProbe, line: bytes) -> None:
    before = probe.protocol_errors
    probe._dispatch(line, time.monotonic_ns())
    samples = probe.read_stream(10, timeout_s=0)
    assert len(samples.seq) + (probe.protocol_errors - before) == 1


@FAST
@given(st.lists(st.tuples(st.integers(0, 1000), st.integers(0, 10**9)), max_size=50))
def test_frame_drop_detector_never_negative(events: list[tuple[int, int]]) -> None:
    detector = FrameDropDetector(60.0)
    for seq, t_ns in events:
        assert detector.update(seq, t_ns) >= 0
