"""``rigctl devices check``: connect every device, print its status and one reading.

The backend comes from ``--backend``, else the configuration's ``rig.backend`` (``sim`` by default).
``sim`` and ``sim-wire`` start a simulated rig (in process, or behind the real drivers on
127.0.0.1); ``real`` builds the drivers from the configuration, which must then be given
(``--config`` or ``$RIGCTL_CONFIG``). Exit status 0 when every device answered, 1 naming the devices
that did not (a device failure), 2 for a usage or configuration mistake.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drivers.interfaces import Camera, Daq, Device, DisplacementProbe, LoadingStage
    from rigctl.config import RigConfig

CHOICES = ("sim", "sim-wire", "real")
READ_TIMEOUT_S = 1.0  # a DAQ that sends nothing for 1 s after starting its stream has failed


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "devices", help="check the rig's devices", description=__doc__.split("\n\n")[0]
    )
    actions = parser.add_subparsers(dest="devices_action", metavar="ACTION")
    actions.required = True
    check = actions.add_parser(
        "check",
        help="connect every device and print its status and a reading",
        description="Connect every device, print each one's status and a reading; exit 1 naming "
        "any device that fails.",
    )
    check.add_argument("--backend", choices=CHOICES, default=None,
                       help="device backend (default: the configuration's rig.backend)")
    check.add_argument("--config", metavar="FILE", default=None, help="rig configuration (TOML)")
    check.set_defaults(func=run_check)


def run_check(args: argparse.Namespace) -> int:
    from rigctl.config import load_effective_config
    from rigctl.errors import UsageError

    config, source = load_effective_config(args.config)
    backend = args.backend or config.rig.backend
    if backend == "real" and source is None:
        raise UsageError(
            "the real backend needs a rig configuration: give --config rig.toml "
            "(or set $RIGCTL_CONFIG); `rigctl config show > rig.toml` writes a template"
        )
    print(f"backend: {backend}; configuration: {source or 'built-in defaults (simulated rig)'}")
    failed: list[str] = []
    with _devices(backend, config, source is not None, failed) as devices:
        for name, device in devices:
            line = _check_one(name, device)
            if line.startswith("FAIL"):
                failed.append(name)
            print(line)
    if failed:
        print(f"rigctl: devices failing: {', '.join(failed)}", file=sys.stderr)
        return 1
    print("all devices answered")
    return 0


@contextlib.contextmanager
def _devices(
    backend: str, config: RigConfig, from_file: bool, failed: list[str]
) -> Iterator[list[tuple[str, Device]]]:
    if backend in ("sim", "sim-wire"):
        from rigctl.config.adapters import sim_settings
        from sim_devices.backends import build_sim_rig

        sim = build_sim_rig(backend, settings=sim_settings(config) if from_file else None, speed=1.0)
        try:
            yield sim.devices.items()
        finally:
            sim.close()
        return
    built: list[tuple[str, Device]] = []
    try:
        for name, make in _real_builders(config):
            try:
                built.append((name, make()))
            except Exception as exc:  # report every device, not just the first failure
                print(f"FAIL  {name:<16} cannot connect: {exc}")
                failed.append(name)
        yield built
    finally:
        for _, device in built:
            with contextlib.suppress(Exception):
                device.close()


def _real_builders(config: RigConfig) -> list[tuple[str, Callable[[], Device]]]:
    from drivers.can_daq import CanDaq
    from drivers.modbus_stage import ModbusStage
    from drivers.opencv_camera import OpenCvCamera
    from drivers.safety import EmergencyStop
    from drivers.serial_probe import SerialProbe
    from rigctl.config import adapters

    estop = EmergencyStop()
    return [
        ("tangential_stage", lambda: ModbusStage(
            adapters.stage_config(config, "tangential_stage"), emergency_stop=estop)),
        ("normal_stage", lambda: ModbusStage(
            adapters.stage_config(config, "normal_stage"), emergency_stop=estop)),
        ("daq", lambda: CanDaq(adapters.daq_config(config))),
        ("d1", lambda: SerialProbe(adapters.probe_config(config, "d1"))),
        ("d2", lambda: SerialProbe(adapters.probe_config(config, "d2"))),
        ("camera", lambda: OpenCvCamera(adapters.camera_config(config))),
    ]


def _check_one(name: str, device: Device) -> str:
    from drivers.interfaces import Camera, Daq, DisplacementProbe, LoadingStage

    try:
        if isinstance(device, LoadingStage):
            detail = _stage(device)
        elif isinstance(device, Daq):
            detail = _daq(device)
        elif isinstance(device, DisplacementProbe):
            detail = _probe(device)
        elif isinstance(device, Camera):
            detail = _camera(device)
        else:
            return f"FAIL  {name:<16} unknown kind of device {type(device).__name__}"
    except Exception as exc:
        return f"FAIL  {name:<16} {type(exc).__name__}: {exc}"
    return f"ok    {name:<16} {detail}"


def _stage(stage: LoadingStage) -> str:
    st = stage.status()
    pos_mm = stage.position_m() * 1e3
    flags = ", ".join(
        f for f, on in (("enabled", st.enabled), ("homed", st.homed), ("moving", st.moving),
                        ("in position", st.in_position), ("limit", st.limit)) if on
    )
    return f"position {pos_mm:.4f} mm; {flags or 'idle'}; alarm {st.alarm_code} ({st.alarm_name})"


def _daq(daq: Daq) -> str:
    daq.start()
    try:
        block = daq.read_block(256, READ_TIMEOUT_S)
    finally:
        daq.stop()
    if len(block) == 0:
        raise TimeoutError(f"no samples within {READ_TIMEOUT_S:g} s of starting the stream")
    m = daq.channel_map
    return (
        f"{len(block)} samples at {daq.rate_hz:g} Hz; Ft {m.ft_N(block).mean():+.2f} N, "
        f"Fn {m.fn_N(block).mean():+.2f} N, D1 {m.d1_m(block).mean() * 1e6:+.3f} um, "
        f"D2 {m.d2_m(block).mean() * 1e6:+.3f} um; dropped {block.dropped_total}"
    )


def _probe(probe: DisplacementProbe) -> str:
    from drivers.errors import OverRangeError

    span = f"range {probe.range_m * 1e6:g} um, resolution {probe.resolution_m * 1e6:g} um"
    try:
        reading = f"{probe.read_m() * 1e6:+.4f} um"
    except OverRangeError as over:  # the probe answered: the target is out of its range
        reading = f"over range ({'+' if over.direction > 0 else '-'})"
    return f"{span}; reading {reading}"


def _camera(camera: Camera) -> str:
    camera.start()
    try:
        frame = camera.read_frame(READ_TIMEOUT_S)
    finally:
        camera.stop()
    img = frame.image
    return (
        f"{img.shape[1]} x {img.shape[0]} px at {camera.frame_rate_hz:g} Hz; frame {frame.seq}, "
        f"mean grey {float(img.mean()):.2f}"
    )
