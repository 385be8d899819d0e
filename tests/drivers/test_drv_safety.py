"""The interfaces' validation and the interlocks, against an in-memory stage that logs its hooks."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from drivers.errors import (
    DeviceError,
    DeviceStateError,
    EmergencyStopActive,
    ForceLimitError,
    InvalidValueError,
    LimitError,
)
from drivers.interfaces import ChannelMap, DaqBlock, LoadingStage, StageLimits, StageStatus
from drivers.safety import EmergencyStop, ForceGuard

LIMITS = StageLimits(min_position_m=0.0, max_position_m=0.025, max_velocity_m_s=1e-3)


class LoggingStage(LoadingStage):
    """Records every hook call; ``on_send`` runs inside a move (to stage races)."""

    def __init__(self, name: str, estop: EmergencyStop, *, fail_stop: bool = False) -> None:
        super().__init__(name, LIMITS, emergency_stop=estop)
        self.log: list[tuple[object, ...]] = []
        self.position = 0.01
        self.fail_stop = fail_stop
        self.on_send = lambda: None

    def _do_enable(self) -> None:
        self.log.append(("enable",))

    def _do_disable(self) -> None:
        self.log.append(("disable",))

    def _do_home(self) -> None:
        self.log.append(("home",))

    def _do_move_absolute(self, target_m: float, velocity_m_s: float) -> None:
        self.on_send()
        self.log.append(("move", target_m, velocity_m_s))

    def _do_stop(self) -> None:
        self.log.append(("stop",))

    def _do_emergency_stop(self) -> None:
        if self.fail_stop:
            raise DeviceError(self.name, "cable cut")
        self.log.append(("estop",))

    def _do_reset_alarm(self) -> None:
        self.log.append(("reset",))

    def _do_position_m(self) -> float:
        return self.position

    def _do_status(self) -> StageStatus:
        return StageStatus(True, True, True, False, False, False)


@pytest.fixture
def stage(estop: EmergencyStop) -> LoggingStage:
    return LoggingStage("normal", estop)


# limits and values ----------------------------------------------------------------------------


def test_valid_move_passes_checked_values(stage: LoggingStage) -> None:
    stage.move_absolute(np.float64(0.02), 5e-6)
    assert stage.log == [("move", 0.02, 5e-6)]


@pytest.mark.parametrize(
    ("target", "velocity", "error"),
    [
        (0.0251, 1e-6, LimitError),
        (-0.001, 1e-6, LimitError),
        (0.01, 2e-3, LimitError),
        (math.nan, 1e-6, InvalidValueError),
        (math.inf, 1e-6, InvalidValueError),
        (0.01, math.nan, InvalidValueError),
        (0.01, 0.0, InvalidValueError),
        (True, 1e-6, InvalidValueError),
        (None, 1e-6, InvalidValueError),
    ],
)
def test_refused_moves_never_reach_the_hook(
    stage: LoggingStage, target: object, velocity: float, error: type[Exception]
) -> None:
    with pytest.raises(error):
        stage.move_absolute(target, velocity)  # type: ignore[arg-type]
    assert stage.log == []


def test_limit_edges_are_allowed_not_clipped(stage: LoggingStage) -> None:
    stage.move_absolute(0.025, 1e-3)
    stage.move_absolute(0.0, 1e-3)
    assert stage.log == [("move", 0.025, 1e-3), ("move", 0.0, 1e-3)]


def test_relative_move_uses_the_current_position(stage: LoggingStage) -> None:
    stage.move_relative(-0.004, 1e-5)
    assert stage.log == [("move", pytest.approx(0.006), 1e-5)]
    with pytest.raises(LimitError):
        stage.move_relative(0.02, 1e-5)
    with pytest.raises(InvalidValueError):
        stage.move_relative(math.nan, 1e-5)


@pytest.mark.parametrize(
    "args",
    [(0.0, 0.0, 1.0), (1.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, math.inf, 1.0), (0.0, 1.0, "1")],
)
def test_stage_limits_validate(args: tuple[object, ...]) -> None:
    with pytest.raises(ValueError):
        StageLimits(*args)  # type: ignore[arg-type]


# emergency stop ---------------------------------------------------------------------------------


def test_trigger_from_many_threads_stops_all_once_latched(estop: EmergencyStop) -> None:
    stages = [LoggingStage(f"s{i}", estop) for i in range(3)]
    barrier = threading.Barrier(8)

    def press(i: int) -> None:
        barrier.wait()
        estop.trigger(f"button {i}")

    threads = [threading.Thread(target=press, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=5)
    assert estop.latched and estop.reason is not None and estop.reason.startswith("button ")
    for s in stages:
        assert ("estop",) in s.log and set(s.log) == {("estop",)}
        with pytest.raises(EmergencyStopActive, match=estop.reason):
            s.move_absolute(0.01, 1e-5)
        with pytest.raises(EmergencyStopActive):
            s.enable()
        with pytest.raises(EmergencyStopActive):
            s.home()
        s.stop()
        s.disable()  # making things safer is never refused
    estop.reset()
    stages[0].move_absolute(0.01, 1e-5)
    assert stages[0].log[-1] == ("move", 0.01, 1e-5)


def test_a_stage_that_fails_to_stop_does_not_spare_the_others(estop: EmergencyStop) -> None:
    broken = LoggingStage("broken", estop, fail_stop=True)
    healthy = LoggingStage("healthy", estop)
    failures = estop.trigger("test")
    assert [f.stage_name for f in failures] == ["broken"]
    assert healthy.log == [("estop",)]
    assert [f.stage_name for f in estop.failures] == ["broken"]
    assert broken.log == []


def test_trigger_racing_a_move_gets_an_immediate_stop(stage: LoggingStage, estop: EmergencyStop) -> None:
    def trigger_in_another_thread() -> None:
        worker = threading.Thread(target=estop.trigger, args=("race",))
        worker.start()
        worker.join()

    stage.on_send = trigger_in_another_thread  # the trigger lands between check and send
    with pytest.raises(EmergencyStopActive):
        stage.move_absolute(0.01, 1e-5)
    assert stage.log == [("estop",), ("move", 0.01, 1e-5), ("estop",)]  # last word: stop


def test_closed_stage_leaves_the_registry(stage: LoggingStage, estop: EmergencyStop) -> None:
    stage.close()
    estop.trigger("after close")
    assert stage.log == []
    with pytest.raises(DeviceStateError):
        stage.move_absolute(0.01, 1e-5)


def test_default_registry_is_process_wide() -> None:
    from drivers.safety import default_emergency_stop

    s = LoggingStage.__new__(LoggingStage)
    LoadingStage.__init__(s, "default-reg", LIMITS)
    try:
        assert s.emergency_stop_registry is default_emergency_stop()
        assert s in default_emergency_stop().stages()
    finally:
        s.close()
    assert s not in default_emergency_stop().stages()


# force guard ----------------------------------------------------------------------------------


def test_force_guard_trips_on_excess_or_nan(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=500.0)
    assert guard.feed(np.array([100.0, -499.9])) is None and not guard.tripped
    trip = guard.feed([499.0, math.nan])
    assert isinstance(trip, ForceLimitError) and math.isnan(trip.force_N)
    assert stage.log == [("estop",)]
    with pytest.raises(ForceLimitError, match="non-finite"):
        stage.move_absolute(0.01, 1e-5)
    guard.reset()
    assert guard.feed(-501.0) is not None  # |Fn| counts: a negative reading trips too
    assert stage.log == [("estop",), ("estop",)]


def test_force_guard_only_blocks_its_own_stage(estop: EmergencyStop) -> None:
    normal = LoggingStage("normal", estop)
    tangential = LoggingStage("tangential", estop)
    ForceGuard(normal).feed([801.0])
    tangential.move_absolute(0.01, 1e-5)
    assert tangential.log == [("move", 0.01, 1e-5)]
    with pytest.raises(ForceLimitError):
        normal.move_absolute(0.01, 1e-5)


def test_force_guard_can_latch_the_emergency_stop(estop: EmergencyStop) -> None:
    normal = LoggingStage("normal", estop)
    tangential = LoggingStage("tangential", estop)
    ForceGuard(normal, also_trigger=estop).feed([900.0])
    assert estop.latched and "900 N" in (estop.reason or "")
    assert ("estop",) in tangential.log
    with pytest.raises(EmergencyStopActive):
        tangential.move_absolute(0.01, 1e-5)


def test_force_guard_detach_and_bad_limit(stage: LoggingStage) -> None:
    guard = ForceGuard(stage)
    guard.feed([1000.0])
    guard.detach()
    stage.move_absolute(0.01, 1e-5)  # no longer guarded
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError):
            ForceGuard(stage, limit_N=bad)


# channel map and blocks -------------------------------------------------------------------------


def test_channel_map_validation() -> None:
    with pytest.raises(ValueError, match="cannot both"):
        ChannelMap(ft_axis="fz", fn_axis="fz")
    with pytest.raises(ValueError, match="sign"):
        ChannelMap(fn_sign=2)
    with pytest.raises(ValueError, match="d1_channel"):
        ChannelMap(d1_channel=3)
    with pytest.raises(ValueError, match="d2_m_per_V"):
        ChannelMap(d2_m_per_V=math.nan)


def test_daq_block_times_from_counter_and_shape_checks() -> None:
    block = DaqBlock.from_counts(
        np.array([1000, 1001, 1003]),
        np.array([[1, 2, 3]] * 3),
        np.array([[0, 0, 0]] * 3),
        force_N_per_count=0.02,
        volts_per_count=1.0,
        rate_hz=1024.0,
        host_monotonic_ns=5,
        dropped_total=1,
        counter_origin=1000,
    )
    np.testing.assert_allclose(block.t_s, [0.0, 1 / 1024, 3 / 1024])
    assert len(block) == 3 and block.fz_N[0] == pytest.approx(0.06)
    with pytest.raises(ValueError, match="ain_V"):
        DaqBlock(
            counter=np.zeros(2, np.int64),
            t_s=np.zeros(2),
            fx_N=np.zeros(2),
            fy_N=np.zeros(2),
            fz_N=np.zeros(2),
            ain_V=np.zeros((2, 2)),
            host_monotonic_ns=0,
            dropped_total=0,
            rate_hz=1024.0,
        )


def test_force_guard_allows_a_release_but_stops_a_release_that_raises_the_force(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=300.0)
    guard.feed([305.0])
    assert guard.tripped
    guard.allow_release()
    assert guard.releasing and not guard.tripped
    assert guard.feed([310.0, 306.0]) is None  # above the limit, below 1.05 x 305 N: releasing
    assert guard.feed([299.0, 260.0]) is None  # within the limit but not clearly below it
    assert guard.feed([300.5]) is None  # hovering at the limit (noise) does not re-trip
    assert guard.releasing
    assert guard.feed([284.0, 250.0]) is None  # below (1 - 0.05) x the limit: release mode ends
    assert not guard.releasing
    assert guard.feed([301.0]) is not None  # the normal limit applies again
    guard.allow_release()
    assert guard.feed([330.0]) is not None  # the force rose during the release: stopped
    assert guard.tripped
