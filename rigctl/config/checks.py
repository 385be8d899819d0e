"""Checks that involve more than one key (single keys are checked against their declaration).

Each check names the key to change. They catch what would otherwise surface as a refused or, worse,
a wrong command on the wire: a limit beyond the travel, a position or velocity the INT32 registers
cannot carry, an unknown model effect, a `real` rig without addresses.
"""

from __future__ import annotations

import difflib

from drivers.can_frames import FULL_SCALE_COUNTS
from drivers.modbus_codec import INT32_MAX
from rigctl.config.adapters import StageName, daq_config, stage_config
from rigctl.config.errors import ConfigError
from rigctl.config.schema import NormalStage, RigConfig, StageLink, TangentialStage


def check_config(config: RigConfig) -> None:
    """Raise :class:`ConfigError` at the first inconsistency."""
    _check_stage(config, "tangential_stage")
    _check_stage(config, "normal_stage")
    _check_force_range(config)
    ch = config.channels
    if ch.d1_channel == ch.d2_channel:
        _fail("channels.d2_channel", f"D1 and D2 cannot both be analog input {ch.d1_channel}")
    if config.sim.effects:
        _check_effects(config.sim.effects)
    if config.rig.backend == "real":
        _check_real(config)


def _check_effects(effects: tuple[str, ...]) -> None:
    from rigctl.model import effect_names  # the physics library, imported only when needed

    known = effect_names()
    for name in effects:
        if name not in known:
            match = difflib.get_close_matches(name, known, n=1)
            hint = f' (did you mean "{match[0]}"?)' if match else f"; known: {', '.join(known)}"
            _fail("sim.effects", f'unknown effect "{name}"{hint}')
    if len(set(effects)) != len(effects):
        _fail("sim.effects", "lists an effect twice")


def _check_stage(config: RigConfig, name: StageName) -> None:
    stage: TangentialStage | NormalStage = getattr(config, name)
    limits = stage.limits
    if not limits.min_position_m < limits.max_position_m:
        _fail(
            f"{name}.limits.max_position_m",
            f"must be above min_position_m ({limits.min_position_m:g} m), got {limits.max_position_m:g} m",
        )
    counts = max(abs(limits.min_position_m), abs(limits.max_position_m)) * stage.counts_per_m
    if counts > INT32_MAX:
        _fail(
            f"{name}.counts_per_m",
            f"{stage.counts_per_m:g} counts/m puts {limits.max_position_m:g} m at {counts:.0f} "
            "counts, beyond INT32",
        )
    v_counts = limits.max_velocity_m_s * stage.velocity_counts_per_m_s
    if v_counts > INT32_MAX:
        _fail(
            f"{name}.limits.max_velocity_m_s",
            f"{limits.max_velocity_m_s:g} m/s is {v_counts:.0f} velocity counts, beyond INT32",
        )
    if stage.transport == "rtu" and not stage.serial_port:
        _fail(f"{name}.serial_port", 'transport "rtu" needs the serial device')
    try:
        stage_config(config, name)
    except ValueError as exc:  # the driver's own checks, as a backstop
        _fail(name, str(exc))


def _check_force_range(config: RigConfig) -> None:
    """The normal-force limit must be within the force sensor's range: past it a reading is
    saturated, so the force guard could not see the load reach the limit."""
    limit_N = config.normal_stage.limits.max_force_N
    range_N = daq_config(config).saturation_N  # the range the drivers and the dry run use
    if limit_N > range_N:
        _fail(
            "normal_stage.limits.max_force_N",
            f"{limit_N:g} N is above the force sensor's range {range_N:g} N (daq.force_range_N, "
            f"at most {FULL_SCALE_COUNTS} x daq.force_N_per_count): a reading there is saturated, "
            "so the force guard could not see the load reach the limit; lower the limit or "
            "configure a sensor that reads it",
        )


def _check_real(config: RigConfig) -> None:
    for name in ("tangential_stage", "normal_stage"):
        stage: StageLink = getattr(config, name)
        if stage.transport == "tcp" and stage.port == 0:
            _fail(f"{name}.port", 'a "real" rig needs the Modbus TCP port (e.g. 502)')
    for probe in ("d1", "d2"):
        if not getattr(config.probes, probe).url:
            _fail(f"probes.{probe}.url", 'a "real" rig needs the probe\'s serial port')
    if config.camera.source == "sim":
        _fail("camera.source", 'a "real" rig needs a camera device index or URL, not "sim"')


def _fail(key: str, message: str) -> None:
    raise ConfigError(f"{key}: {message}", key=key)
