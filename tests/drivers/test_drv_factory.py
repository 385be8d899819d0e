"""Building drivers from plain dict configuration; every mistake names its key."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pytest

from drivers.can_daq import CanDaq
from drivers.factory import (
    ConfigError,
    build_device,
    build_devices,
    driver_kinds,
    register_driver,
)
from drivers.interfaces import Device
from drivers.modbus_stage import NORMAL_COUNTS_PER_M, ModbusStage
from drivers.opencv_camera import OpenCvCamera
from drivers.safety import EmergencyStop
from drivers.serial_probe import SerialProbe

from .drv_can_peer import fresh_channel


def test_modbus_stage_from_role_with_partial_limit_override(estop: EmergencyStop) -> None:
    stage = build_device(
        {
            "kind": "modbus_stage",
            "role": "normal",
            "host": "127.0.0.1",
            "port": 1502,
            "word_order": "low_first",
            "limits": {"max_velocity_m_s": 1e-4},
            "registers": {"alarm_code": 12},
        },
        emergency_stop=estop,
    )
    try:
        assert isinstance(stage, ModbusStage)
        cfg = stage.config
        assert stage.name == "normal_stage"
        assert cfg.counts_per_m == NORMAL_COUNTS_PER_M
        assert (cfg.limits.max_position_m, cfg.limits.max_velocity_m_s) == (0.025, 1e-4)
        assert (cfg.port, cfg.word_order, cfg.registers.alarm_code) == (1502, "low_first", 12)
        assert stage in estop.stages()
    finally:
        stage.close()


@pytest.mark.parametrize(
    ("config", "path", "words"),
    [
        ({"kind": "modbus_stage", "role": "normal", "prot": 1}, "device.prot", "unknown key"),
        (
            {"kind": "modbus_stage", "role": "normal", "limits": {"max_position_m": "abc"}},
            "device.limits.max_position_m",
            "expected a number",
        ),
        ({"kind": "modbus_stage", "role": "sideways"}, "device.role", "expected one of"),
        ({"kind": "modbus_stage", "name": "x"}, "device.limits", "missing required key"),
        ({"kind": "modbus_stage", "role": "normal", "port": 5.5}, "device.port", "integer"),
        ({"kind": "modbus_stage", "role": "normal", "port": 70000}, "device", "port"),
        (
            {"kind": "modbus_stage", "role": "normal", "word_order": "big"},
            "device.word_order",
            "expected one of",
        ),
        (
            {"kind": "modbus_stage", "role": "normal", "limits": {"max_velocity_m_s": float("nan")}},
            "device.limits.max_velocity_m_s",
            "finite",
        ),
        (
            {"kind": "can_daq", "channel_map": {"fn_axis": "fq"}},
            "device.channel_map.fn_axis",
            "expected one of",
        ),
        (
            {"kind": "can_daq", "channel_map": {"fn_axis": "fx"}},
            "device.channel_map",
            "cannot both be fx",
        ),
        ({"kind": "can_daq", "rate_hz": 1024.5}, "device", "whole number"),
        ({"kind": "serial_probe", "timeout_s": True}, "device.timeout_s", "number"),
        (
            {"kind": "opencv_camera", "source": 1.5},
            "device.source",
            "expected an integer or a string, got 1.5",
        ),
        ({"kind": "laser"}, "device.kind", "unknown driver kind"),
        ({"role": "normal"}, "device.kind", "missing"),
    ],
)
def test_mistakes_name_the_key(config: dict[str, Any], path: str, words: str) -> None:
    with pytest.raises(ConfigError, match=words) as info:
        build_device(config, emergency_stop=EmergencyStop())
    assert info.value.path == path
    assert str(info.value).startswith(path)
    assert isinstance(info.value, ValueError)


def test_build_devices_all_kinds(tmp_path: Any) -> None:
    estop = EmergencyStop()
    devices = build_devices(
        {
            "tangential_stage": {"kind": "modbus_stage", "role": "tangential"},
            "daq": {
                "kind": "can_daq",
                "channel": fresh_channel(),
                "channel_map": {"fn_axis": "fz", "fn_sign": -1, "d1_m_per_V": 7.4e-6},
            },
            "probe1": {"kind": "serial_probe", "url": "loop://"},
            "camera": {"kind": "opencv_camera", "source": str(tmp_path / "x.avi")},
        },
        emergency_stop=estop,
    )
    try:
        assert isinstance(devices["tangential_stage"], ModbusStage)
        assert devices["tangential_stage"].name == "tangential_stage"
        daq = devices["daq"]
        assert isinstance(daq, CanDaq) and daq.channel_map.fn_sign == -1
        assert isinstance(devices["probe1"], SerialProbe) and devices["probe1"].name == "probe1"
        assert isinstance(devices["camera"], OpenCvCamera)
    finally:
        for device in devices.values():
            device.close()


def test_build_devices_closes_what_it_built_when_one_fails() -> None:
    estop = EmergencyStop()
    with pytest.raises(ConfigError, match=r"devices\.bad\.kind"):
        build_devices(
            {"normal": {"kind": "modbus_stage", "role": "normal"}, "bad": {"kind": "nope"}},
            emergency_stop=estop,
        )
    assert estop.stages() == []  # the normal stage was built, then closed (unregistered)


def test_register_a_new_kind() -> None:
    built: list[Mapping[str, Any]] = []

    class Dummy(Device):
        pass

    def make(settings: Mapping[str, Any], path: str, estop: EmergencyStop | None) -> Device:
        built.append(settings)
        return Dummy(str(settings["name"]))

    register_driver("dummy_for_test", make)
    assert "dummy_for_test" in driver_kinds()
    device = build_device({"kind": "dummy_for_test", "name": "d"})
    assert device.name == "d" and built == [{"name": "d"}]
