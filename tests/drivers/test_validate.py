"""One check of configured numbers (drivers/validate.py), used by every configuration class."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from drivers.can_daq import CanDaqConfig
from drivers.errors import InputError, SettingError
from drivers.interfaces import StageLimits
from drivers.modbus_stage import TANGENTIAL_LIMITS, StageConfig
from drivers.opencv_camera import CameraConfig
from drivers.serial_probe import ProbeConfig
from drivers.validate import bound_problem, check_integer, check_number
from rigctl.config.errors import ConfigError
from rigctl.config.loader import parse_config
from sim_devices.modbus_stage_server import StageWireConfig
from sim_devices.virtual_rig import VirtualRigConfig


@pytest.mark.parametrize(
    ("value", "bounds", "problem"),
    [
        (1.0, {"gt": 0.0}, None),
        (0.0, {"gt": 0.0, "unit": "s"}, "must be > 0 s"),
        (-1.0, {"ge": 0.0, "unit": "m"}, "must be >= 0 m"),
        (900.0, {"gt": 0.0, "le": 800.0, "unit": "N"}, "must be <= 800 N"),
        (1.0, {"lt": 1.0}, "must be < 1"),
        (math.nan, {}, "must be finite"),
        (math.inf, {"gt": 0.0}, "must be finite"),
        (2.5, {"integer": True, "ge": 1}, "must be a whole number"),
        (0.0, {"integer": True, "ge": 1}, "must be >= 1"),
    ],
)
def test_bound_problem(value: float, bounds: dict[str, Any], problem: str | None) -> None:
    assert bound_problem(value, **bounds) == problem


def test_check_number_and_integer() -> None:
    assert check_number("o", "k", np.float32(0.5), gt=0.0) == 0.5
    with pytest.raises(SettingError, match=r"^o: k = True: must be a number$"):
        check_number("o", "k", True)
    with pytest.raises(SettingError, match=r"^o: k = '1': must be a number$"):
        check_number("o", "k", "1")
    with pytest.raises(SettingError) as info:
        check_number("probe 'd1'", "timeout_s", -1, unit="s", gt=0.0)
    err = info.value
    assert (err.owner, err.key, err.value, err.reason) == ("probe 'd1'", "timeout_s", -1, "must be > 0 s")
    assert isinstance(err, InputError) and isinstance(err, ValueError)
    assert check_integer("o", "retries", 3, 0, 3) == 3
    for bad in (4, -1, 1.0, True):
        with pytest.raises(SettingError, match=r"must be an integer in 0\.\.3"):
            check_integer("o", "retries", bad, 0, 3)


@pytest.mark.parametrize(
    ("build", "key", "words"),
    [
        (lambda: StageConfig("t", TANGENTIAL_LIMITS, 3.125e6, timeout_s=-1.0), "timeout_s", "> 0 s"),
        (lambda: StageConfig("t", TANGENTIAL_LIMITS, math.nan), "counts_per_m", "finite"),
        (lambda: StageConfig("t", TANGENTIAL_LIMITS, 3.125e6, retries=9), "retries", r"0\.\.3"),
        (lambda: ProbeConfig(timeout_s=math.inf), "timeout_s", "finite"),
        (lambda: ProbeConfig(stream_silence_s=0), "stream_silence_s", "> 0 s"),
        (lambda: CanDaqConfig(command_timeout_s=0.0), "command_timeout_s", "> 0 s"),
        (lambda: CanDaqConfig(force_N_per_count="0.02"), "force_N_per_count", "a number"),
        (lambda: CameraConfig(frame_rate_hz=-60.0), "frame_rate_hz", "> 0 Hz"),
        (lambda: CameraConfig(queue_size=0), "queue_size", r"1\.\.10000"),
        (lambda: StageLimits(0.0, 0.2, -1e-3), "max_velocity_m_s", "> 0"),
        (lambda: VirtualRigConfig(max_load_N=900.0), "max_load_N", "<= 800 N"),
        (lambda: VirtualRigConfig(history_s=0.01), "history_s", ">= 0.0625 s"),
        (lambda: StageWireConfig(counts_per_m=0.0), "counts_per_m", "> 0 counts/m"),
        (lambda: StageWireConfig(counts_per_m=1.0, device_id=0), "device_id", r"1\.\.247"),
    ],
)
def test_device_and_simulator_configs_name_the_key_and_unit(build: Any, key: str, words: str) -> None:
    with pytest.raises(SettingError, match=words) as info:
        build()
    assert info.value.key == key


def test_rig_configuration_bounds_carry_the_unit() -> None:
    with pytest.raises(ConfigError) as info:
        parse_config("[daq]\ncommand_timeout_s = -1", source="rig.toml")
    assert str(info.value) == "rig.toml: daq.command_timeout_s: must be > 0, got -1 s"
    with pytest.raises(ConfigError) as info:
        parse_config("[normal_stage.limits]\nmax_velocity_m_s = -1e-3", source="rig.toml")
    assert str(info.value).startswith("rig.toml: normal_stage.limits.max_velocity_m_s: must be > 0")
