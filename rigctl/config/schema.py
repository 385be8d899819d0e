# ruff: noqa: RUF009  (setting() and section() return dataclasses.field(...), which is safe)
"""The rig configuration: typed, frozen sections, one per device, with defaults for the simulated rig.

The defaults are the configuration used when no file is given, and they describe the simulated rig
(``backend = "sim"``), so every command works on a fresh clone without hardware. Wire-level values
(register map, word order, scales, CAN ids, probe protocol) follow docs/protocols.md; rated values
come from the paper's rig (Han et al. 2022, Section 2.1): normal stroke 25 mm, tangential stroke
200 mm, maximum normal load 800 N, sampling at 1024 Hz, camera at 60 Hz.

A key's unit is in its name (``max_force_N``, ``timeout_s``); its meaning, unit and bounds are in its
:func:`~rigctl.config.fields.setting` declaration, from which docs/configuration.md is generated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from drivers.can_daq import DEFAULT_FORCE_N_PER_COUNT
from drivers.can_frames import FULL_SCALE_COUNTS
from drivers.interfaces import ChannelMap, StageLimits
from drivers.modbus_codec import RegisterMap, WordOrder
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    NORMAL_LIMITS,
    TANGENTIAL_COUNTS_PER_M,
    TANGENTIAL_LIMITS,
    VELOCITY_COUNTS_PER_M_S,
)
from drivers.safety import DEFAULT_FORCE_LIMIT_N
from rigctl.config.fields import Setting, describe, section, setting

RATED_NORMAL_FORCE_N = DEFAULT_FORCE_LIMIT_N
"""Maximum load of the normal loading stage: 800 N (Han et al. 2022, Section 2.1)."""
NORMAL_STROKE_M = NORMAL_LIMITS.max_position_m
"""Travel of the normal loading stage: 25 mm (Han et al. 2022, Section 2.1)."""
TANGENTIAL_STROKE_M = TANGENTIAL_LIMITS.max_position_m
"""Travel of the tangential stage: 200 mm (Han et al. 2022, Section 2.1)."""
DEFAULT_FORCE_RANGE_N = round(FULL_SCALE_COUNTS * DEFAULT_FORCE_N_PER_COUNT, 9)
"""The force sensor's default range: the DAQ's full scale at the default force scale, 32767 counts x
0.025 N/count = 819.175 N, which covers the normal stage's rated 800 N (rounded to the nanonewton)."""

Backend = Literal["sim", "sim-wire", "real"]
Transport = Literal["tcp", "rtu"]
Compression = Literal["gzip", "lzf", "none"]
ModelBase = Literal["paper", "classic"]
Parity = Literal["N", "E", "O"]

describe(
    RegisterMap,  # the drivers' register map (docs/protocols.md), used as each `registers` table
    control=Setting("Address of the control bits (write).", ge=0, le=65534),
    status=Setting("Address of the status bits (read).", ge=0, le=65534),
    target_position=Setting("Address of the target position (INT32, 2 registers).", ge=0, le=65534),
    velocity=Setting("Address of the velocity (INT32, 2 registers).", ge=0, le=65534),
    actual_position=Setting("Address of the actual position (INT32, 2 registers).", ge=0, le=65534),
    alarm_code=Setting("Address of the alarm code (UINT16).", ge=0, le=65534),
)

describe(
    ChannelMap,  # the drivers' channel map, used as the `channels` table
    ft_axis=Setting("Force-sensor axis carrying the tangential force Ft."),
    ft_sign=Setting("Sign applied to that axis to give Ft (+1 or -1)."),
    fn_axis=Setting("Force-sensor axis carrying the normal force Fn."),
    fn_sign=Setting("Sign applied to that axis to give Fn (+1 or -1)."),
    d1_channel=Setting("Analog input (ain0..ain2) of displacement probe D1.", ge=0, le=2),
    d1_m_per_V=Setting("D1 analog scale (74 um over 10 V).", unit="m/V"),
    d2_channel=Setting("Analog input (ain0..ain2) of displacement probe D2.", ge=0, le=2),
    d2_m_per_V=Setting("D2 analog scale (74 um over 10 V).", unit="m/V"),
    probe_rail_V=Setting("A probe output at or beyond this is over range (at the rail): counted "
                         "and marked in the run, never taken as a displacement.", unit="V", gt=0),
)


@dataclass(frozen=True)
class RigSection:
    name: str = setting("simulated stick-slip rig", "Name of the rig, stored with every run.")
    backend: Backend = setting(
        "sim",
        "Which devices to use: `sim` (simulated devices in process), `sim-wire` (simulators "
        "behind the real drivers and protocols on 127.0.0.1), `real` (the hardware).",
    )
    operator: str = setting("", "Default operator name stored with runs.")


@dataclass(frozen=True)
class TangentialLimits(StageLimits):
    """The tangential stage's :class:`~drivers.interfaces.StageLimits`, with its defaults."""

    min_position_m: float = setting(0.0, "Lowest target a move may have.", unit="m", ge=0.0)
    max_position_m: float = setting(
        TANGENTIAL_STROKE_M, "Highest target a move may have.", unit="m", le=TANGENTIAL_STROKE_M
    )
    max_velocity_m_s: float = setting(
        TANGENTIAL_LIMITS.max_velocity_m_s,
        "Fastest velocity a move may ask for.",
        unit="m/s",
        gt=0.0,
    )


@dataclass(frozen=True)
class NormalLimits(StageLimits):
    """The normal stage's :class:`~drivers.interfaces.StageLimits`, with its defaults and force limit."""

    min_position_m: float = setting(0.0, "Lowest target a move may have.", unit="m", ge=0.0)
    max_position_m: float = setting(
        NORMAL_STROKE_M, "Highest target a move may have.", unit="m", le=NORMAL_STROKE_M
    )
    max_velocity_m_s: float = setting(
        NORMAL_LIMITS.max_velocity_m_s,
        "Fastest velocity a move may ask for.",
        unit="m/s",
        gt=0.0,
    )
    max_force_N: float = setting(
        RATED_NORMAL_FORCE_N,
        "Normal-force limit: |Fn| above it emergency-stops the normal stage. At most the force "
        "sensor's range (daq.force_range_N, itself at most 32767 x daq.force_N_per_count): a "
        "larger limit is refused, since the guard could not read the load past the range.",
        unit="N",
        gt=0.0,
        le=RATED_NORMAL_FORCE_N,
    )
    contact_search_end_m: float = setting(
        0.02005,
        "Furthest position the contact search may reach without reading a contact: the expected "
        "contact position plus its uncertainty, which must stay well below the load path's "
        "deflection at the force limit. Past it the load step stops and fails (a blind force reading "
        "must not push the stage into the specimen). Default: this rig's contact at 20.0 mm + 50 um "
        "(247 N of approach).",
        unit="m",
        gt=0.0,
        le=NORMAL_STROKE_M,
    )
    max_approach_m: float = setting(
        115e-6,
        "Furthest the normal stage may press past the position where it first read a contact: the "
        "load path's deflection at the lower of max_force_N and the force sensor's range "
        "(daq.force_range_N), with a small margin. The configuration knows no contact stiffness, so "
        "set it with the force limit: load a specimen to that force once with a sound sensor and "
        "read the approach from the run file (Fn against the normal stage's position), and lower "
        "both together (this rig: 109 um at 800 N, 80 um at 500 N). A load step that would go "
        "further stops and fails, so a blind, frozen or saturated force reading presses at most "
        "this plus one contact-search step past the contact.",
        unit="m",
        gt=0.0,
    )


@dataclass(frozen=True)
class StageLink:
    """How to reach one stage controller over Modbus, and its wire scales (drivers.StageConfig)."""

    transport: Transport = setting("tcp", "Modbus transport (`rtu` = serial).")
    host: str = setting("127.0.0.1", "Modbus TCP host.")
    port: int = setting(
        0,
        "Modbus TCP port; 0 lets the simulators pick a free one (`real` needs a port, e.g. 502).",
        ge=0,
        le=65535,
    )
    serial_port: str = setting("", "Serial device for `rtu` (e.g. `/dev/ttyUSB0`).")
    baudrate: int = setting(115200, "Serial baud rate for `rtu`.", unit="bit/s", ge=1, le=1e7)
    parity: Parity = setting("N", "Serial parity for `rtu`.")
    stopbits: int = setting(1, "Serial stop bits for `rtu`.", ge=1, le=2)
    bytesize: int = setting(8, "Serial data bits for `rtu`.", ge=5, le=8)
    device_id: int = setting(1, "Modbus device (unit) id.", ge=0, le=247)
    word_order: WordOrder = setting("high_first", "Register order of 32-bit values.")
    counts_per_m: float = setting(TANGENTIAL_COUNTS_PER_M, "Position scale.", unit="counts/m", gt=0.0)
    velocity_counts_per_m_s: float = setting(
        VELOCITY_COUNTS_PER_M_S, "Velocity scale (1e9: nm/s).", unit="counts/(m/s)", gt=0.0
    )
    timeout_s: float = setting(0.3, "Reply timeout per attempt.", unit="s", gt=0.0, le=10.0)
    retries: int = setting(1, "Retries after a timeout before the device is declared dead.", ge=0, le=3)
    registers: RegisterMap = section(RegisterMap, "Register map.")


@dataclass(frozen=True)
class TangentialStage(StageLink):
    counts_per_m: float = setting(
        TANGENTIAL_COUNTS_PER_M, "Position scale (0.32 um/count).", unit="counts/m", gt=0.0
    )
    limits: TangentialLimits = section(TangentialLimits, "Motion limits (refused, never clipped).")


@dataclass(frozen=True)
class NormalStage(StageLink):
    counts_per_m: float = setting(
        NORMAL_COUNTS_PER_M, "Position scale (0.6 um/count).", unit="counts/m", gt=0.0
    )
    limits: NormalLimits = section(NormalLimits, "Motion and force limits.")


@dataclass(frozen=True)
class DaqSection:
    """The DAQ shim on the CAN bus (docs/protocols.md; drivers.can_daq.CanDaqConfig)."""

    interface: str = setting(
        "virtual", "python-can interface (`virtual`, `udp_multicast`, `socketcan`, `pcan`, ...)."
    )
    channel: str = setting("rigctl", "python-can channel (e.g. `can0`).")
    bitrate: int = setting(1_000_000, "CAN bit rate; 0 leaves it to the interface.", unit="bit/s", ge=0)
    node_id: int = setting(1, "Node id: data on 0x180/0x280 + node, commands on 0x600 + node.", ge=1, le=127)
    sample_rate_hz: int = setting(1024, "Sample rate of forces and probes.", unit="Hz", ge=1, le=65535)
    force_N_per_count: float = setting(
        DEFAULT_FORCE_N_PER_COUNT,
        "Force scale: 32767 counts (the int16 full scale) are the most the DAQ can read, 819.175 N "
        "at the default, which covers the normal stage's rated 800 N.",
        unit="N/count",
        gt=0.0,
    )
    force_range_N: float = setting(
        DEFAULT_FORCE_RANGE_N,
        "The force sensor's range: a reading this large is saturated (at least this much), so the "
        "force guard trips there, and a normal-force limit (normal_stage.limits.max_force_N) or a "
        "force target above it is refused before anything moves. Used as at most the DAQ's full "
        "scale, 32767 counts x force_N_per_count; the default is that full scale at the default "
        "scale; the simulated sensor's range is the full scale at force_N_per_count.",
        unit="N",
        gt=0.0,
    )
    volts_per_count: float = setting(10.0 / 32768.0, "Analog scale.", unit="V/count", gt=0.0)
    command_timeout_s: float = setting(0.3, "Reply timeout of a command.", unit="s", gt=0.0, le=10.0)
    command_retries: int = setting(1, "Retries of an unanswered command.", ge=0, le=3)
    stream_silence_s: float = setting(
        0.5,
        "Silence of a started stream after which the DAQ is declared dead.",
        unit="s",
        gt=0.0,
    )
    rx_queue_size: int = setting(
        8192,
        "Bound of the receive queue (python-can's is unbounded by default).",
        unit="frames",
        ge=16,
        le=1 << 22,
    )


@dataclass(frozen=True)
class ProbeSection:
    """One fibre-optic displacement probe on its serial line (drivers.serial_probe.ProbeConfig)."""

    url: str = setting(
        "",
        "pyserial URL or port (`/dev/ttyUSB0`, `socket://host:port`, `loop://`); "
        "empty: the simulators provide one (`real` needs it).",
    )
    baudrate: int = setting(115200, "Serial baud rate.", unit="bit/s", ge=1, le=1e7)
    timeout_s: float = setting(0.3, "Reply timeout.", unit="s", gt=0.0, le=10.0)
    retries: int = setting(1, "Retries of an unanswered command.", ge=0, le=3)
    stream_silence_s: float = setting(
        0.5,
        "Silence of a started stream after which the probe is declared dead.",
        unit="s",
        gt=0.0,
    )
    range_m: float = setting(74e-6, "Measuring range, centred on the zero.", unit="m", gt=0.0)
    resolution_m: float = setting(1.9e-8, "Resolution (quantisation step).", unit="m", gt=0.0)


@dataclass(frozen=True)
class Probes:
    d1: ProbeSection = section(ProbeSection, "Probe D1.")
    d2: ProbeSection = section(ProbeSection, "Probe D2.")


@dataclass(frozen=True)
class CameraSection:
    """The contact camera (drivers.opencv_camera.CameraConfig; frame size for the run file)."""

    source: str = setting(
        "sim",
        "`sim` (rendered from the model's contact state), a device index (`0`) or a path/URL "
        "for cv2.VideoCapture.",
    )
    width_px: int = setting(640, "Frame width.", unit="px", ge=1, le=16384)
    height_px: int = setting(480, "Frame height.", unit="px", ge=1, le=16384)
    frame_rate_hz: float = setting(60.0, "Frame rate.", unit="Hz", gt=0.0, le=1000.0)
    queue_size: int = setting(8, "Frames buffered between camera and recorder.", ge=1, le=10000)


@dataclass(frozen=True)
class StorageSection:
    directory: str = setting("runs", "Folder for run files (relative: to the working folder).")
    flush_interval_s: float = setting(
        0.25, "Longest time between flushes of a run file.", unit="s", gt=0.0, le=0.5
    )
    frame_compression: Compression = setting(
        "gzip",
        "Compression of camera frames, built into HDF5 (no plug-in needed to read): gzip (deflate "
        "level 1, 126 kB per 640 x 480 contact image), lzf (191 kB), none (307 kB, the least CPU; "
        "for images that do not compress). docs/run-file.md.",
    )
    min_free_bytes: int = setting(
        64 * 2**20, "Free space kept in reserve beyond a run's estimated size: a run that would "
        "leave less is refused before anything moves, and recording stops (the file closed with "
        "its status) when less than half of it is left.", unit="B", ge=0
    )


@dataclass(frozen=True)
class SimSection:
    """The simulated rig's physics (used by the `sim` and `sim-wire` backends)."""

    model: ModelBase = setting("paper", "Base model of the simulated physics (docs/model.md).")
    effects: tuple[str, ...] = setting((), "Effects added to the base model (docs/model.md).")
    seed: int = setting(0, "Seed of the simulators' noise.", ge=0)


@dataclass(frozen=True)
class RigConfig:
    """The whole rig configuration (one TOML file)."""

    rig: RigSection = section(RigSection, "The rig.")
    tangential_stage: TangentialStage = section(TangentialStage, "Tangential (drive) stage.")
    normal_stage: NormalStage = section(NormalStage, "Normal loading stage.")
    daq: DaqSection = section(DaqSection, "DAQ over CAN.")
    channels: ChannelMap = section(ChannelMap, "Channel map (which input is Ft, Fn, D1, D2).")
    probes: Probes = section(Probes, "Displacement probes.")
    camera: CameraSection = section(CameraSection, "Contact camera.")
    storage: StorageSection = section(StorageSection, "Run files.")
    sim: SimSection = section(SimSection, "Simulated physics.")
