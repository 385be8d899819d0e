"""Open the rig for a backend: the simulated rig (in process or behind the wires) or the hardware.

``open_rig`` yields an :class:`OpenRig` with the devices behind the drivers' interfaces, the limits of
the configuration, and (simulated backends) the running virtual rig.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from experiments.context import Controls, RigLimits
from experiments.protocols import Protocol
from experiments.runner import Runner, RunProgressFn
from rigctl.acquisition import Acquisition, RigDevices
from rigctl.config import RigConfig, adapters
from rigctl.config.errors import ConfigError
from rigctl.config.loader import to_toml
from rigctl.errors import UsageError
from rigctl.model import ModelSpec
from rigctl.storage.layout import RunDescription

MAX_SPEED = math.inf
"""``--speed max``: a simulated rig paced by the acquisition (:class:`Pacer`), as fast as the CPU allows
while the recorded data never falls more than ``Pacer.max_lag_s`` of rig time behind."""


STALL_S = 0.2
"""Host seconds without new recorded data after which the paced rig runs on at real time."""

TICK_S = 0.005
"""Host seconds between advances of a speed-capped paced rig (the free-running rig's ``tick_s``)."""


class Pacer:
    """Advances a manual-clock virtual rig in small steps, as fast as the acquisition keeps up.

    A free-running accelerated clock can outrun the recorder: the data read would then lag the rig,
    stage positions polled "now" would not match the samples they are stored with, and waits measured
    on the data would jump. Pacing keeps the rig at most ``max_lag_s`` of rig time ahead of the newest
    recorded sample, so every reading is current to within that.

    ``speed`` caps the rig's clock at that many rig seconds per host second (``--speed N``; ``inf``
    for ``--speed max``). A rig held back by the recorder does not catch up afterwards: the cap counts
    from where it resumed. The rig is also held within ``max_lag_s`` of the earliest rig time a
    simulated device still owes output for (``VirtualRig.owed_s``: the camera's next frame), so a
    camera renders every frame of its rate in rig time, and ``--speed max`` runs as fast as
    rendering allows. Before :meth:`follow` a capped rig runs at ``speed``, an uncapped one
    waits. Every advance is pinned on the rig's clock (``SimClock.pin``), so host timestamps of
    simulated devices (camera frames) follow the rig's actual progress.
    """

    def __init__(
        self,
        rig: Any,
        step_s: float = 1.0 / 16.0,
        max_lag_s: float = 0.25,
        speed: float = MAX_SPEED,
    ) -> None:
        if not speed > 0:
            raise ValueError(f"pacer speed must be positive, got {speed!r}")
        self.rig = rig
        self.step_s = step_s
        self.max_lag_s = max_lag_s
        self.speed = speed
        self._data_time: Callable[[], float] | None = None
        self._offset: float | None = None
        self._t_follow = 0.0
        self._anchor: tuple[float, float] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim-pacer", daemon=True)
        self.error: BaseException | None = None

    def follow(self, data_time: Callable[[], float]) -> None:
        """Pace against ``data_time()`` (device time of the newest recorded sample, NaN before)."""
        self._offset = None
        self._t_follow = self.rig.t_s
        self._data_time = data_time

    def start(self) -> Pacer:
        self.rig.clock.pin(self.rig.t_s)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)

    def _lag_s(self, t_data: float) -> float:
        """Rig time minus the newest recorded sample (``t_data``), on the rig's time axis.

        The data's time axis starts when the DAQ stream started; the offset between the two axes is
        the minimum of (rig time - data time) seen so far: every observation is the offset plus a
        lag >= 0, so the minimum only ever over-estimates how far the data may fall behind by the
        smallest lag seen, and pacing can never wait for data the rig has not produced yet.
        """
        if t_data != t_data:  # NaN: no data yet: run ahead of where pacing began, but no further
            return self.rig.t_s - self._t_follow
        observed = self.rig.t_s - t_data
        self._offset = observed if self._offset is None else min(self._offset, observed)
        return observed - self._offset

    def _owed_lag_s(self) -> float:
        """Rig time minus the earliest rig time a device still owes output for (-inf: none)."""
        return float(self.rig.t_s - self.rig.owed_s())

    def _advance_to(self, t_s: float) -> None:
        self.rig.advance_to(t_s)
        self.rig.clock.pin(self.rig.t_s)

    def _capped(self, now: float) -> float | None:
        """Where the speed cap lets the rig go now (None: nowhere yet, wait a tick)."""
        target = self.rig.t_s + self.step_s
        if math.isinf(self.speed):
            return target
        if self._anchor is None:
            self._anchor = (now, self.rig.t_s)
        cap = self._anchor[1] + self.speed * (now - self._anchor[0])
        if cap >= target:
            return target
        return cap if cap - self.rig.t_s >= self.speed * TICK_S else None

    def _run(self) -> None:
        try:
            last_data = float("nan")
            last_owed = math.inf
            last_progress = time.monotonic()
            while not self._stop.is_set():
                now = time.monotonic()
                if self._data_time is None and math.isinf(self.speed):
                    self._stop.wait(0.001)
                    continue
                owed = float(self.rig.owed_s())
                if owed != last_owed:
                    last_owed, last_progress = owed, now
                lag = self._owed_lag_s()
                if self._data_time is not None:
                    t_data = self._data_time()
                    lag = max(lag, self._lag_s(t_data))
                    if t_data == t_data and t_data != last_data:
                        last_data, last_progress = t_data, now
                if lag > self.max_lag_s:
                    self._anchor = None  # held: the speed cap restarts where the rig resumes
                    if now - last_progress < STALL_S:  # the recorder / camera is catching up: wait
                        self._stop.wait(0.001)
                        continue
                    # no recorded data and no frame for STALL_S (a silent DAQ or camera, a stopped
                    # acquisition): the rig's clock goes on at real time, so timeouts and a
                    # safe-state retraction still happen
                    self._stop.wait(self.step_s)
                    self._advance_to(self.rig.t_s + self.step_s)
                    continue
                target = self._capped(now)
                if target is None:
                    self._stop.wait(TICK_S)
                    continue
                self._advance_to(target)
        except BaseException as exc:  # surfaces as silent devices, and here for the record
            self.error = exc


@dataclass
class OpenRig:
    devices: RigDevices
    limits: RigLimits
    config: RigConfig
    speed: float
    sim: Any = None
    """The SimRig of a simulated backend (its virtual rig, faults), None for the hardware."""
    pacer: Pacer | None = None
    """An accelerated simulated rig's pacer; :meth:`runner` makes it follow the acquisition."""
    backend: str = field(default="real", kw_only=True)
    """``sim``, ``sim-wire`` or ``real``: what :func:`open_rig` opened (stated in run files)."""

    @property
    def speed_text(self) -> str:
        """The rig's clock as ``--speed`` says it: ``1``, ``N`` or ``max``."""
        return "max" if math.isinf(self.speed) else f"{self.speed:g}"

    def runner(
        self,
        protocol: Protocol[Any],
        given: Mapping[str, Any],
        *,
        out: Path | None,
        camera: bool = True,
        operator: str | None = None,
        notes: str = "",
        metadata: Mapping[str, str] | None = None,
        controls: Controls | None = None,
        progress: RunProgressFn | None = None,
        overwrite: bool = False,
        on_acquisition: Callable[[Acquisition], None] | None = None,
    ) -> Runner:
        """The one way to build a run of ``protocol`` on this rig: ``rigctl run``, the window's
        in-process worker and the run service all call it, so their run files say the same.

        The run file gets the configuration's layouts, force limit, flush interval and free-space
        reserve (``storage.min_free_bytes``), and metadata
        ``backend``, ``speed``, ``rig``, the caller's ``metadata`` (where the run was started
        from) and the rig's stated parameters (:meth:`stated_parameters`). ``operator`` defaults
        to the configuration's. An accelerated simulated rig is paced by the recorded data
        (``pacer.follow``) before ``on_acquisition`` is called with the acquisition.
        """
        config = self.config
        description = RunDescription(
            protocol=protocol.name,
            operator=operator if operator is not None else config.rig.operator,
            notes=notes, config_toml=to_toml(config),
            metadata={"backend": self.backend, "speed": self.speed_text, "rig": config.rig.name,
                      **(metadata or {}), **self.stated_parameters()},
        )
        pacer = self.pacer

        def acquisition_started(acq: Acquisition) -> None:
            if pacer is not None:
                pacer.follow(lambda: acq.t_s)
            if on_acquisition is not None:
                on_acquisition(acq)

        return Runner(
            protocol, dict(given), self.devices, self.limits, out=out,
            daq_layout=adapters.daq_layout(config),
            camera_layout=adapters.camera_layout(config) if camera else None,
            description=description, controls=controls,
            force_limit_N=adapters.force_limit_N(config), progress=progress,
            flush_interval_s=config.storage.flush_interval_s, overwrite=overwrite,
            on_acquisition=acquisition_started, min_free_bytes=config.storage.min_free_bytes,
        )

    def stated_parameters(self) -> dict[str, str]:
        """``rig.<parameter>`` metadata for this rig's run files: the simulated rig states its
        model's mass and drive damping (:func:`rigctl.model.simulator.stated_rig_parameters`), so
        the workbench need not fit them; the hardware states nothing it does not know."""
        if self.sim is None:
            return {}
        from rigctl.model.simulator import stated_rig_parameters

        return stated_rig_parameters(self.sim.rig.model)


def rig_limits(config: RigConfig) -> RigLimits:
    """The limits the dry run checks a plan against: the same objects the stage drivers get (the
    force sensor's range as the DAQ driver takes it from the configuration)."""
    from rigctl.config.adapters import daq_config

    n = config.normal_stage.limits
    return RigLimits(tangential=config.tangential_stage.limits, normal=n, max_force_N=n.max_force_N,
                     contact_search_end_m=n.contact_search_end_m, max_approach_m=n.max_approach_m,
                     force_range_N=daq_config(config).saturation_N)


def parse_speed(text: str) -> float:
    """'1', '20', 'max' -> a clock factor for a simulated rig."""
    if text == "max":
        return MAX_SPEED
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"--speed must be a number or 'max', got {text!r}") from None
    if not (v > 0 and v < float("inf")):
        raise UsageError(f"--speed must be positive and finite, got {text!r}")
    if not SPEED_RANGE[0] <= v <= SPEED_RANGE[1]:
        raise UsageError(f"--speed {text}: a simulated rig runs from real time (1) to "
                         f"{SPEED_RANGE[1]:g} times faster; use --speed max for as fast as it can")
    return v


SPEED_RANGE = (1.0, 1000.0)
"""Clock factors accepted for a simulated rig: slower than real time serves nobody (the devices'
timeouts are in host time) and above 1000 the rig is paced by the CPU anyway (``max``)."""


@contextlib.contextmanager
def open_rig(
    backend: str, config: RigConfig, speed: float = 1.0, model: ModelSpec | None = None
) -> Iterator[OpenRig]:
    """Open the devices of ``backend``; a simulated rig runs ``model`` (default: the config's)."""
    if backend in ("sim", "sim-wire"):
        from sim_devices.backends import build_sim_rig

        # an accelerated rig keeps the configured frame rate in rig time: its pacer waits for the
        # frames the camera still owes (VirtualRig.owe), so rendering sets how fast it can go
        cam_cfg = config.camera
        from sim_devices.contact_image import MAX_HEIGHT_PX, MAX_WIDTH_PX

        if cam_cfg.width_px > MAX_WIDTH_PX or cam_cfg.height_px > MAX_HEIGHT_PX:
            raise ConfigError(
                f"camera {cam_cfg.width_px} x {cam_cfg.height_px} px: the simulated camera renders "
                f"at most {MAX_WIDTH_PX} x {MAX_HEIGHT_PX} px (every frame is drawn from the "
                "contact state in real time); set camera.width_px/height_px within that, or use "
                "the real backend", key="camera.width_px")
        paced = speed > 1.0  # an accelerated rig must not outrun its recorder (Pacer)
        from rigctl.config.adapters import sim_settings

        sim = build_sim_rig(backend, settings=sim_settings(config), speed=None if paced else speed,
                            model=model)
        pacer = Pacer(sim.rig, speed=speed).start() if paced else None
        try:
            # the rig's clock says where "now" is on the recorded axis: positions polled, step
            # markers and waits are placed there, not at the newest sample the recorder has read
            devices = RigDevices.from_device_set(sim.devices, device_now_s=sim.rig.daq_time_now_s)
            yield OpenRig(devices, rig_limits(config), config, speed, sim, pacer,
                          backend=backend)
        finally:
            if pacer is not None:
                pacer.stop()
            sim.close()
        return
    if backend != "real":
        raise UsageError(f"unknown backend {backend!r} (sim, sim-wire, real)")
    if speed != 1.0:
        raise UsageError("the real rig runs in real time only (--speed 1)")
    from drivers.can_daq import CanDaq
    from drivers.modbus_stage import ModbusStage
    from drivers.opencv_camera import OpenCvCamera
    from drivers.safety import EmergencyStop
    from drivers.serial_probe import SerialProbe
    from rigctl.config import adapters

    estop = EmergencyStop()
    opened: list[Any] = []
    try:
        tang = ModbusStage(adapters.stage_config(config, "tangential_stage"), emergency_stop=estop)
        opened.append(tang)
        normal = ModbusStage(adapters.stage_config(config, "normal_stage"), emergency_stop=estop)
        opened.append(normal)
        daq = CanDaq(adapters.daq_config(config))
        opened.append(daq)
        d1 = SerialProbe(adapters.probe_config(config, "d1"))
        opened.append(d1)
        d2 = SerialProbe(adapters.probe_config(config, "d2"))
        opened.append(d2)
        cam = OpenCvCamera(adapters.camera_config(config))
        opened.append(cam)
        yield OpenRig(RigDevices(tang, normal, daq, cam, d1, d2), rig_limits(config), config, 1.0,
                      backend=backend)
    finally:
        for dev in reversed(opened):
            with contextlib.suppress(Exception):
                dev.close()
