"""From the rig configuration to the devices' own configuration objects (no second definition).

The drivers and simulators define what they need (``drivers.modbus_stage.StageConfig``,
``drivers.can_daq.CanDaqConfig``, ``drivers.serial_probe.ProbeConfig``,
``drivers.opencv_camera.CameraConfig``, ``sim_devices.virtual_rig.VirtualRigConfig``); the register map
and the channel map are the drivers' own classes used directly as TOML tables. These functions hand
the rest over, so the devices' own checks apply to what the file says.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Literal

from drivers.can_daq import CanDaqConfig
from drivers.modbus_stage import StageConfig
from drivers.opencv_camera import CameraConfig
from drivers.serial_probe import ProbeConfig
from rigctl.config.errors import ConfigError
from rigctl.config.schema import NormalStage, RigConfig, TangentialStage
from rigctl.storage.layout import CameraLayout, DaqLayout

if TYPE_CHECKING:  # the simulators pull in the physics engine: imported only when asked for
    from sim_devices.backends import SimSettings
    from sim_devices.virtual_rig import VirtualRigConfig

StageName = Literal["tangential_stage", "normal_stage"]
ProbeName = Literal["d1", "d2"]


def stage_config(config: RigConfig, which: StageName) -> StageConfig:
    """The :class:`drivers.modbus_stage.StageConfig` of one stage (named like the TOML table)."""
    stage: TangentialStage | NormalStage = getattr(config, which)
    return StageConfig(
        name=which.removesuffix("_stage"),
        limits=stage.limits,  # a StageLimits: the driver checks moves against these
        counts_per_m=stage.counts_per_m,
        transport=stage.transport,
        host=stage.host,
        port=stage.port,
        serial_port=stage.serial_port,
        baudrate=stage.baudrate,
        parity=stage.parity,
        stopbits=stage.stopbits,
        bytesize=stage.bytesize,
        device_id=stage.device_id,
        word_order=stage.word_order,
        velocity_counts_per_m_s=stage.velocity_counts_per_m_s,
        timeout_s=stage.timeout_s,
        retries=stage.retries,
        registers=stage.registers,
    )


def force_limit_N(config: RigConfig) -> float:
    """The normal-force limit for :class:`drivers.safety.ForceGuard`."""
    return config.normal_stage.limits.max_force_N


def daq_config(config: RigConfig) -> CanDaqConfig:
    """The :class:`drivers.can_daq.CanDaqConfig` of the DAQ (with the channel map)."""
    d = config.daq
    return CanDaqConfig(
        name="daq",
        interface=d.interface,
        channel=d.channel,
        bitrate=d.bitrate or None,
        node_id=d.node_id,
        rate_hz=float(d.sample_rate_hz),
        force_N_per_count=d.force_N_per_count,
        force_range_N=d.force_range_N,
        volts_per_count=d.volts_per_count,
        command_timeout_s=d.command_timeout_s,
        command_retries=d.command_retries,
        stream_silence_s=d.stream_silence_s,
        rx_queue_size=d.rx_queue_size,
        channel_map=config.channels,
    )


def probe_config(config: RigConfig, which: ProbeName, url: str | None = None) -> ProbeConfig:
    """The :class:`drivers.serial_probe.ProbeConfig` of probe ``d1`` or ``d2``.

    ``url`` overrides the configured one (a simulated probe's pty); an empty URL without an
    override is a :class:`ConfigError` naming the key.
    """
    p = getattr(config.probes, which)
    chosen = url if url is not None else p.url
    if not chosen:
        raise ConfigError(f"probes.{which}.url: no serial port configured", key=f"probes.{which}.url")
    return ProbeConfig(
        name=which,
        url=chosen,
        baudrate=p.baudrate,
        timeout_s=p.timeout_s,
        retries=p.retries,
        stream_silence_s=p.stream_silence_s,
    )


def camera_config(config: RigConfig) -> CameraConfig:
    """The :class:`drivers.opencv_camera.CameraConfig` of a real camera (``source`` not ``sim``)."""
    c = config.camera
    if c.source == "sim":
        raise ConfigError(
            'camera.source: "sim" is the simulated camera, not an OpenCV source', key="camera.source"
        )
    source: int | str = int(c.source) if c.source.isdigit() else c.source
    return CameraConfig(name="camera", source=source, frame_rate_hz=c.frame_rate_hz, queue_size=c.queue_size)


def daq_layout(config: RigConfig) -> DaqLayout:
    """The run file's DAQ stream: the default channels at the configured sample rate."""
    return DaqLayout(sample_rate_hz=float(config.daq.sample_rate_hz))


def camera_layout(config: RigConfig) -> CameraLayout:
    """The run file's camera stream: frame size, rate and compression from the configuration."""
    c = config.camera
    return CameraLayout(
        height_px=c.height_px,
        width_px=c.width_px,
        frame_rate_hz=c.frame_rate_hz,
        compression=config.storage.frame_compression,
    )


def virtual_rig_config(config: RigConfig) -> VirtualRigConfig:
    """The :class:`sim_devices.virtual_rig.VirtualRigConfig` of the simulated rig (rate, probes, seed)."""
    from sim_devices.virtual_rig import VirtualRigConfig

    base = VirtualRigConfig()
    probes = tuple(
        dataclasses.replace(spec, range_m=section.range_m, resolution_m=section.resolution_m)
        for spec, section in zip(base.probes, (config.probes.d1, config.probes.d2), strict=True)
    )
    d1, d2 = probes
    return dataclasses.replace(
        base,
        sample_rate_hz=float(config.daq.sample_rate_hz),
        probes=(d1, d2),
        seed=config.sim.seed,
    )


def sim_settings(config: RigConfig) -> SimSettings:
    """What the simulated rig (:func:`sim_devices.backends.build_sim_rig`) takes from ``config``:
    the model, the virtual rig, the drivers' settings, the sensor scales, the camera."""
    from rigctl.model import build_model
    from sim_devices.backends import SimSettings
    from sim_devices.contact_image import CameraOptics
    from sim_devices.sensors import ForceSensorSpec

    sensor = dataclasses.replace(
        ForceSensorSpec(),
        force_N_per_count=config.daq.force_N_per_count,
        volts_per_count=config.daq.volts_per_count,
        probe_m_per_volt=config.channels.d1_m_per_V,
    )
    placeholder = "loop://"  # replaced by the simulated probe's pty
    return SimSettings(
        model=build_model(base=config.sim.model, effects=list(config.sim.effects)),
        rig=virtual_rig_config(config),
        tangential_stage=stage_config(config, "tangential_stage"),
        normal_stage=stage_config(config, "normal_stage"),
        daq=daq_config(config),
        sensor=sensor,
        channel_map=config.channels,
        probes=(probe_config(config, "d1", url=placeholder), probe_config(config, "d2", url=placeholder)),
        camera_optics=CameraOptics(
            width_px=config.camera.width_px,
            height_px=config.camera.height_px,
            seed=config.sim.seed + 2022,
        ),
        camera_frame_rate_hz=config.camera.frame_rate_hz,
    )


__all__ = [
    "ProbeName",
    "StageName",
    "camera_config",
    "camera_layout",
    "daq_config",
    "daq_layout",
    "force_limit_N",
    "probe_config",
    "sim_settings",
    "stage_config",
    "virtual_rig_config",
]
