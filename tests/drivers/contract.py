"""Behaviour every implementation of an interface must show, as pytest mixins (microscope style).

Use from any test package::

    from tests.drivers.contract import StageContract

    class TestMySimStage(StageContract):
        @pytest.fixture
        def stage(self, estop):          # estop: a private EmergencyStop the stage registers with
            with MySimStage(..., emergency_stop=estop) as s:
                yield s

Each mixin only uses the public interface. Fixtures to provide: ``stage`` + ``estop`` (stages),
``daq`` (a started-able Daq whose device streams once started), ``probe`` (with a stream source),
``camera`` (a Camera delivering at least 4 frames).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from drivers.errors import (
    DeviceStateError,
    EmergencyStopActive,
    InvalidValueError,
    LimitError,
    OverRangeError,
)
from drivers.interfaces import Camera, Daq, DaqBlock, DisplacementProbe, LoadingStage, StageStatus
from drivers.safety import EmergencyStop


class StageContract:
    """A stage moves within its limits, refuses beyond them, obeys the emergency stop."""

    position_tolerance_m = 1e-6
    move_timeout_s = 5.0

    def _target(self, stage: LoadingStage, fraction: float) -> float:
        lim = stage.limits
        return lim.min_position_m + fraction * (lim.max_position_m - lim.min_position_m)

    def _speed(self, stage: LoadingStage) -> float:
        return stage.limits.max_velocity_m_s

    def test_status_is_a_stage_status(self, stage: LoadingStage) -> None:
        status = stage.status()
        assert isinstance(status, StageStatus)
        assert isinstance(status.alarm_name, str)

    def test_move_within_limits_arrives(self, stage: LoadingStage) -> None:
        stage.enable()
        target = self._target(stage, 0.5) + 0.001 * (
            stage.limits.max_position_m - stage.limits.min_position_m
        )
        stage.move_absolute(target, self._speed(stage))
        status = stage.wait_for_motion(self.move_timeout_s)
        assert not status.moving and not status.fault
        assert stage.position_m() == pytest.approx(target, abs=self.position_tolerance_m)

    def test_relative_move(self, stage: LoadingStage) -> None:
        stage.enable()
        stage.move_absolute(self._target(stage, 0.5), self._speed(stage))
        stage.wait_for_motion(self.move_timeout_s)
        start = stage.position_m()
        delta = 0.01 * (stage.limits.max_position_m - stage.limits.min_position_m)
        stage.move_relative(-delta, self._speed(stage))
        stage.wait_for_motion(self.move_timeout_s)
        assert stage.position_m() == pytest.approx(start - delta, abs=self.position_tolerance_m)

    def test_beyond_limits_refused_and_nothing_moves(self, stage: LoadingStage) -> None:
        stage.enable()
        before = stage.position_m()
        lim = stage.limits
        span = lim.max_position_m - lim.min_position_m
        for target, velocity in (
            (lim.max_position_m + 1e-3 * span, self._speed(stage)),
            (lim.min_position_m - 1e-3 * span, self._speed(stage)),
            (self._target(stage, 0.5), 1.01 * lim.max_velocity_m_s),
        ):
            with pytest.raises(LimitError):
                stage.move_absolute(target, velocity)
        for bad in (math.nan, math.inf):
            with pytest.raises(InvalidValueError):
                stage.move_absolute(bad, self._speed(stage))
        assert not stage.status().moving
        assert stage.position_m() == pytest.approx(before, abs=self.position_tolerance_m)

    def test_emergency_stop_latches_and_resets(self, stage: LoadingStage, estop: EmergencyStop) -> None:
        stage.enable()
        estop.trigger("contract test")
        with pytest.raises(EmergencyStopActive):
            stage.move_absolute(self._target(stage, 0.5), self._speed(stage))
        assert not stage.status().moving
        estop.reset()
        stage.reset_alarm()
        stage.enable()
        stage.move_absolute(self._target(stage, 0.5), self._speed(stage))
        stage.wait_for_motion(self.move_timeout_s)


class DaqContract:
    """A DAQ streams samples timed by their counter and counts what it loses."""

    def _collect(self, daq: Daq, n: int, timeout_s: float = 3.0) -> list[DaqBlock]:
        blocks, got = [], 0
        deadline = time.monotonic() + timeout_s
        while got < n and time.monotonic() < deadline:
            block = daq.read_block(n - got, timeout_s=0.2)
            assert isinstance(block, DaqBlock)
            if len(block):
                blocks.append(block)
                got += len(block)
        return blocks

    def test_stream_timed_by_counter(self, daq: Daq) -> None:
        daq.start()
        try:
            blocks = self._collect(daq, 64)
        finally:
            daq.stop()
        counter = np.concatenate([b.counter for b in blocks])
        t_s = np.concatenate([b.t_s for b in blocks])
        assert len(counter) == 64
        assert np.all(np.diff(counter) >= 1)
        np.testing.assert_allclose(np.diff(t_s), np.diff(counter) / daq.rate_hz, rtol=1e-9)
        assert counter[-1] - counter[0] + 1 == 64 + blocks[-1].dropped_total - blocks[0].dropped_total
        drops = [b.dropped_total for b in blocks]
        assert drops == sorted(drops)
        for b in blocks:
            assert b.ain_V.shape == (len(b), 3)
            assert np.all(np.isfinite(b.fx_N)) and np.all(np.isfinite(b.ain_V))

    def test_set_rate_refused_while_streaming(self, daq: Daq) -> None:
        daq.start()
        try:
            with pytest.raises(DeviceStateError):
                daq.set_rate(2 * daq.rate_hz)
        finally:
            daq.stop()

    def test_bad_arguments_refused(self, daq: Daq) -> None:
        for bad in (math.nan, 0.0, -1.0):
            with pytest.raises(InvalidValueError):
                daq.set_rate(bad)
        with pytest.raises(InvalidValueError):
            daq.read_block(0, timeout_s=0.1)
        with pytest.raises(InvalidValueError):
            daq.read_block(10, timeout_s=math.nan)


class ProbeContract:
    """A probe reads within its range (or says it is out of range) and streams numbered samples."""

    stream_rate_hz = 1024.0

    def test_range_and_resolution(self, probe: DisplacementProbe) -> None:
        assert probe.range_m > 0
        assert 0 < probe.resolution_m <= probe.range_m

    def test_single_reading_in_range_or_over_range(self, probe: DisplacementProbe) -> None:
        try:
            value = probe.read_m()
        except OverRangeError as over:
            assert over.direction in (1, -1)
            return
        assert math.isfinite(value) and abs(value) <= probe.range_m / 2 + probe.resolution_m

    def test_stream_numbered_and_never_clipped(self, probe: DisplacementProbe) -> None:
        probe.start_stream(self.stream_rate_hz)
        try:
            with pytest.raises(DeviceStateError):
                probe.read_m()
            seq, values, host_ns = probe.read_stream(32, timeout_s=1.0)
        finally:
            probe.stop_stream()
        assert len(seq) > 0 and len(seq) == len(values) == len(host_ns)
        assert np.all(np.diff(seq) >= 1) and np.all(np.diff(host_ns) >= 0)
        finite = values[np.isfinite(values)]
        assert not np.any(np.isnan(values))
        assert np.all(np.abs(finite) <= probe.range_m / 2 + probe.resolution_m)


class CameraContract:
    """A camera delivers numbered, timestamped 8-bit frames."""

    def test_frames_numbered_and_timestamped(self, camera: Camera) -> None:
        camera.start()
        try:
            frames = [camera.read_frame(timeout_s=2.0) for _ in range(4)]
        finally:
            camera.stop()
        for f in frames:
            assert f.image.dtype == np.uint8 and f.image.ndim == 2
        for a, b in zip(frames, frames[1:], strict=False):
            assert b.seq > a.seq and b.t_monotonic_ns > a.t_monotonic_ns
            assert b.dropped_before >= b.seq - a.seq - 1

    def test_bad_exposure_refused(self, camera: Camera) -> None:
        with pytest.raises(InvalidValueError):
            camera.exposure_s = math.nan
        with pytest.raises(InvalidValueError):
            camera.exposure_s = -1.0
