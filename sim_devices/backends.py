"""Build a whole simulated rig and hand back its devices: backends ``sim`` and ``sim-wire``.

- ``sim``: the in-process backend (:mod:`sim_devices.inprocess`) on one :class:`VirtualRig`.
- ``sim-wire``: the wire-level simulators on loopback (two Modbus TCP stage servers on 127.0.0.1 with
  OS-chosen ports, the DAQ node on a python-can ``virtual`` channel, the probes behind ptys) and the
  REAL drivers (:class:`ModbusStage`, :class:`CanDaq`, :class:`SerialProbe`) connected to them.

Both give a :class:`DeviceSet` with the same six devices and the same names as the configuration
(``tangential_stage``, ``normal_stage``, ``daq``, ``d1``, ``d2``, ``camera``); the camera is the
in-process :class:`SimCamera` in both (OpenCV has no pluggable backend). Everything a backend
started is stopped by :meth:`SimRig.close` (or leaving :func:`open_sim_rig`), drivers first.

What a rig configuration says about the simulated rig reaches this module as :class:`SimSettings`
(made by :func:`rigctl.config.adapters.sim_settings`): the simulators depend on the drivers and the
model only, never on rigctl's configuration.

Each simulated device has its own :class:`~sim_devices.faults.Faults` in :attr:`SimRig.faults`,
keyed by the device names. The stages register with :attr:`SimRig.emergency_stop`, a fresh
:class:`EmergencyStop` per simulated rig unless one is given (a simulated rig must not latch the
process-wide one that a real rig in the same process would use).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Literal

from drivers.can_daq import CanDaq, CanDaqConfig
from drivers.interfaces import Camera, ChannelMap, Daq, Device, DisplacementProbe, LoadingStage
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    NORMAL_LIMITS,
    TANGENTIAL_COUNTS_PER_M,
    TANGENTIAL_LIMITS,
    ModbusStage,
    StageConfig,
)
from drivers.safety import EmergencyStop
from drivers.serial_probe import ProbeConfig, SerialProbe
from rigctl.model import ModelSpec, build_model
from sim_devices.camera_sim import SimCamera
from sim_devices.can_daq_sim import CanDaqSim, CanDaqSimConfig
from sim_devices.contact_image import CameraOptics
from sim_devices.faults import Faults
from sim_devices.inprocess import InProcessDaq, InProcessProbe, InProcessStage
from sim_devices.modbus_stage_server import ModbusStageServer, StageWireConfig
from sim_devices.probe_sim import ProbeSim
from sim_devices.sensors import ForceSensorSpec
from sim_devices.virtual_rig import StageControl, VirtualRig, VirtualRigConfig

_log = logging.getLogger(__name__)

BackendName = Literal["sim", "sim-wire"]
BACKENDS: tuple[BackendName, ...] = ("sim", "sim-wire")
DEVICE_NAMES = ("tangential_stage", "normal_stage", "daq", "d1", "d2", "camera")


@dataclass
class DeviceSet:
    """The rig's six devices behind the drivers' interfaces."""

    tangential_stage: LoadingStage
    normal_stage: LoadingStage
    daq: Daq
    d1: DisplacementProbe
    d2: DisplacementProbe
    camera: Camera

    def items(self) -> list[tuple[str, Device]]:
        """(name, device) in a fixed order."""
        return [(name, getattr(self, name)) for name in DEVICE_NAMES]

    def close(self) -> None:
        """Close every device (the camera and streams first); errors are logged, not raised."""
        for name, device in reversed(self.items()):
            try:
                if isinstance(device, Camera) and device.running:
                    device.stop()
                device.close()
            except Exception as exc:  # one failing close must not keep the others open
                _log.warning("closing %s failed: %s", name, exc)


@dataclass
class SimRig:
    """A running simulated rig: the virtual rig, its devices, their faults, what to shut down."""

    backend: BackendName
    rig: VirtualRig
    devices: DeviceSet
    faults: dict[str, Faults]
    emergency_stop: EmergencyStop
    servers: list[object] = field(default_factory=list)
    _closers: list[Callable[[], None]] = field(default_factory=list, repr=False)
    _closed: bool = field(default=False, repr=False)

    def close(self) -> None:
        """Close the drivers, then the simulators (in reverse order of start), then the rig."""
        if self._closed:
            return
        self._closed = True
        self.devices.close()
        for closer in reversed(self._closers):
            try:
                closer()
            except Exception as exc:
                _log.warning("stopping a simulator failed: %s", exc)
        self.rig.close()


def _default_stage(name: str) -> StageConfig:
    counts, limits = ((TANGENTIAL_COUNTS_PER_M, TANGENTIAL_LIMITS) if name == "tangential"
                      else (NORMAL_COUNTS_PER_M, NORMAL_LIMITS))
    return StageConfig(name=name, limits=limits, counts_per_m=counts)


@dataclass(frozen=True)
class SimSettings:
    """Everything a simulated rig takes from a rig configuration; the defaults are the devices' own.

    :func:`rigctl.config.adapters.sim_settings` makes one from a :class:`rigctl.config.RigConfig`.
    """

    model: ModelSpec | None = None
    """The friction model (None: :func:`rigctl.model.build_model`'s default)."""
    rig: VirtualRigConfig = field(default_factory=VirtualRigConfig)
    tangential_stage: StageConfig = field(default_factory=lambda: _default_stage("tangential"))
    normal_stage: StageConfig = field(default_factory=lambda: _default_stage("normal"))
    daq: CanDaqConfig | None = None
    """The DAQ driver's settings (None: the driver's defaults, sampling at the rig's rate)."""
    sensor: ForceSensorSpec = field(default_factory=ForceSensorSpec)
    channel_map: ChannelMap | None = None
    probes: tuple[ProbeConfig, ProbeConfig] | None = None
    """The probe drivers' settings (their ``url`` is replaced by the simulated probe's pty)."""
    camera_optics: CameraOptics | None = None
    camera_frame_rate_hz: float = 60.0


def build_sim_rig(
    backend: str = "sim",
    *,
    settings: SimSettings | None = None,
    model: ModelSpec | None = None,
    speed: float | None = 1.0,
    rig_config: VirtualRigConfig | None = None,
    camera_optics: CameraOptics | None = None,
    emergency_stop: EmergencyStop | None = None,
    can_channel: str | None = None,
) -> SimRig:
    """Start a simulated rig with ``backend`` (``sim`` or ``sim-wire``); the caller closes it.

    ``settings`` (:class:`SimSettings`, e.g. ``rigctl.config.adapters.sim_settings(config)``) supplies
    the model, seed, sample rate, probe specs, camera size and the drivers' settings; the explicit
    arguments override it. ``speed`` is the
    clock's factor (1 real time, >1 accelerated, None manual: advance with ``rig.advance_to``).
    ``can_channel`` defaults to a unique ``virtual`` channel, so parallel rigs never hear each other.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown simulated backend {backend!r}; one of {', '.join(BACKENDS)}")
    cfg = settings if settings is not None else SimSettings()
    if model is None:
        model = cfg.model if cfg.model is not None else build_model()
    rig = VirtualRig(model, speed=speed, config=rig_config if rig_config is not None else cfg.rig)
    estop = emergency_stop if emergency_stop is not None else EmergencyStop()
    optics = camera_optics if camera_optics is not None else cfg.camera_optics
    faults = {name: Faults(seed=rig.config.seed + 10 * i) for i, name in enumerate(DEVICE_NAMES)}
    closers: list[Callable[[], None]] = []
    try:
        camera = SimCamera(
            rig,
            "camera",
            optics=optics,
            frame_rate_hz=cfg.camera_frame_rate_hz,
            faults=faults["camera"],
        )
        if backend == "sim":
            devices = _in_process(rig, cfg, faults, estop, camera)
            sim = SimRig("sim", rig, devices, faults, estop)
        else:
            devices, servers = _wire(rig, cfg, faults, estop, camera, can_channel, closers)
            sim = SimRig("sim-wire", rig, devices, faults, estop, servers, closers)
    except BaseException:
        for closer in reversed(closers):
            with contextlib.suppress(Exception):
                closer()
        rig.close()
        raise
    rig.start()
    return sim


@contextlib.contextmanager
def open_sim_rig(backend: str = "sim", **kwargs: object) -> Iterator[SimRig]:
    """:func:`build_sim_rig` as a context manager that shuts everything down on exit."""
    sim = build_sim_rig(backend, **kwargs)  # type: ignore[arg-type]
    try:
        yield sim
    finally:
        sim.close()


def _in_process(
    rig: VirtualRig,
    settings: SimSettings,
    faults: dict[str, Faults],
    estop: EmergencyStop,
    camera: SimCamera,
) -> DeviceSet:
    rate = settings.daq.rate_hz if settings.daq is not None else rig.rate_hz

    def stage(control: StageControl, cfg: StageConfig, key: str) -> InProcessStage:
        return InProcessStage(control, cfg.counts_per_m, name=cfg.name, limits=cfg.limits,
                              emergency_stop=estop, faults=faults[key], timeout_s=cfg.timeout_s)

    return DeviceSet(
        tangential_stage=stage(rig.tangential, settings.tangential_stage, "tangential_stage"),
        normal_stage=stage(rig.normal, settings.normal_stage, "normal_stage"),
        daq=InProcessDaq(rig, "daq", rate_hz=rate, sensor=settings.sensor,
                         channel_map=settings.channel_map,
                         faults=faults["daq"], seed=rig.config.seed),
        d1=InProcessProbe(rig, 0, "d1", faults=faults["d1"]),
        d2=InProcessProbe(rig, 1, "d2", faults=faults["d2"]),
        camera=camera,
    )


def _wire(
    rig: VirtualRig,
    settings: SimSettings,
    faults: dict[str, Faults],
    estop: EmergencyStop,
    camera: SimCamera,
    can_channel: str | None,
    closers: list[Callable[[], None]],
) -> tuple[DeviceSet, list[object]]:
    servers: list[object] = []
    stages: list[ModbusStage] = []
    for control, cfg, key in zip(
        (rig.tangential, rig.normal), (settings.tangential_stage, settings.normal_stage),
        ("tangential_stage", "normal_stage"),
        strict=True,
    ):
        wire = StageWireConfig(
            counts_per_m=cfg.counts_per_m,
            velocity_counts_per_m_s=cfg.velocity_counts_per_m_s,
            word_order=cfg.word_order,
            device_id=max(cfg.device_id, 1),
            registers=cfg.registers,
        )
        server = ModbusStageServer(control, wire, faults=faults[key]).start()
        closers.append(server.stop)
        servers.append(server)
        stage = ModbusStage(dataclasses.replace(cfg, transport="tcp", host=server.host,
                                                port=server.port), emergency_stop=estop)
        closers.append(stage.close)
        stages.append(stage)

    daq_cfg = settings.daq if settings.daq is not None else CanDaqConfig()
    channel = can_channel or f"rigctl-sim-{uuid.uuid4().hex[:12]}"
    daq_cfg = dataclasses.replace(daq_cfg, interface="virtual", channel=channel, bitrate=None)
    node = CanDaqSim(
        rig,
        CanDaqSimConfig(interface="virtual", channel=channel, node_id=daq_cfg.node_id,
                        rate_hz=int(daq_cfg.rate_hz), sensor=settings.sensor,
                        seed=rig.config.seed),
        faults=faults["daq"],
    ).start()
    closers.append(node.stop)
    servers.append(node)
    daq = CanDaq(daq_cfg)
    closers.append(daq.close)

    probes: list[SerialProbe] = []
    for index, key in enumerate(("d1", "d2")):
        psim = ProbeSim(rig, index, faults=faults[key]).start()
        closers.append(psim.stop)
        servers.append(psim)
        spec = rig.probes[index].spec  # the simulated mount is motorised
        base = settings.probes[index] if settings.probes is not None else ProbeConfig(name=key)
        pcfg = dataclasses.replace(base, url=psim.path, mount_travel_m=spec.mount_travel_m,
                                   mount_speed_m_s=spec.mount_speed_m_s)
        probe = SerialProbe(pcfg)
        closers.append(probe.close)
        probes.append(probe)

    devices = DeviceSet(stages[0], stages[1], daq, probes[0], probes[1], camera)
    return devices, servers
