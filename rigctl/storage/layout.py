"""Names, types and small helpers of the HDF5 run-file layout (the contract is docs/run-file.md).

Everything the writer and the reader must agree on lives here: object paths, the fixed-length string
sizes of the fields rewritten while SWMR is on, the default DAQ channels, units derived from channel
names, and the description of the camera stream.
"""

from __future__ import annotations

import platform
import sys
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib import metadata as importlib_metadata
from typing import Any, Literal

import h5py
import numpy as np

from rigctl.status import RunStatus

FORMAT_NAME = "rigctl_run"
FORMAT_VERSION = "1.1"
LIBVER: tuple[Literal["v110"], Literal["v110"]] = ("v110", "v110")
"""Library version bounds: the oldest format with SWMR, readable by HDF5 >= 1.10 tools."""

ENTRY = "entry"
DAQ = "entry/daq"
DAQ_BLOCKS = "entry/daq/blocks"
ROWS_VALID = "entry/daq/rows_valid"
"""(2,) int64: DAQ samples and block-table rows the writer knows are on disk (written, then
flushed); a reader reads no further. Absent in files written before format 1.1."""
CAMERA = "entry/camera"
EVENTS = "entry/events"
PLOT = "entry/plot"
METADATA = "entry/metadata"

FINAL_STATUSES = (RunStatus.COMPLETED, RunStatus.ABORTED, RunStatus.FAILED)

# Fixed-length UTF-8 fields: these are written after SWMR starts, when HDF5 only allows rewriting
# raw data of existing datasets (variable-length strings live in the global heap, which is not).
STATUS_BYTES = 16
END_TIME_BYTES = 40
ERROR_BYTES = 4096
EVENT_NAME_BYTES = 64
EVENT_MESSAGE_BYTES = 1024
TRUNCATION_MARK = " [truncated]"

DAQ_CHUNK_SAMPLES = 4096
BLOCK_CHUNK = 1024
EVENT_CHUNK = 64

DEFAULT_DAQ_CHANNELS: tuple[str, ...] = (
    "ft_N",
    "fn_N",
    "fx_N",
    "fy_N",
    "fz_N",
    "d1_m",
    "d2_m",
    "x_stage_m",
    "z_stage_m",
)
"""What the rig records at the sample rate: Ft and Fn as mapped from the force axes (after signs),
the three raw force axes, both probes, and both stage positions."""

_UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_m_s2", "m/s^2"),
    ("_m_s", "m/s"),
    ("_N", "N"),
    ("_m", "m"),
    ("_s", "s"),
    ("_hz", "Hz"),
    ("_Hz", "Hz"),
    ("_V", "V"),
    ("_C", "degC"),
    ("_K", "K"),
    ("_Pa", "Pa"),
    ("_rad", "rad"),
    ("_counts", "counts"),
)


def unit_of(name: str) -> str:
    """Unit of a channel from its name suffix (``ft_N`` -> ``N``); ``""`` when the name has none."""
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return unit
    return ""


@dataclass(frozen=True)
class DaqLayout:
    """The sampled stream: its channels (all float64, SI units) and nominal sample rate."""

    channels: tuple[str, ...] = DEFAULT_DAQ_CHANNELS
    sample_rate_hz: float = 1024.0
    units: dict[str, str] = field(default_factory=dict)
    """Units for channels whose name suffix does not give one (overrides :func:`unit_of`)."""

    def unit(self, channel: str) -> str:
        return self.units.get(channel, unit_of(channel))


FrameCompression = Literal["gzip", "lzf", "none"]
FRAME_COMPRESSIONS: tuple[FrameCompression, ...] = ("gzip", "lzf", "none")
FRAME_GZIP_LEVEL = 1
"""Deflate level of ``gzip`` frames: levels 4 and 6 save 5-10 % more and write 1.3-8x slower
(benchmarks/bench_frame_compression.py, docs/performance.md)."""

FRAME_BYTES_PER_PIXEL: dict[FrameCompression, float] = {"gzip": 0.411, "lzf": 0.622, "none": 1.0}
"""Stored bytes per pixel of contact images by compression, measured on the simulated camera's
640 x 480 frames (read noise 1.2 grey levels RMS, loads 0-300 N): 126.1, 191.0 and 307.2 kB per
frame (benchmarks/bench_frame_compression.py). Noisier images compress less, up to 1.0."""


def frame_filters(compression: FrameCompression) -> dict[str, Any]:
    """``h5py`` ``create_dataset`` keywords of the frames' compression (filters built into HDF5:
    any h5py or HDF5 user reads them without plug-ins)."""
    if compression == "gzip":
        return {"compression": "gzip", "compression_opts": FRAME_GZIP_LEVEL}
    if compression == "lzf":
        return {"compression": "lzf"}
    if compression == "none":
        return {}
    raise ValueError(
        f"frame compression must be one of {', '.join(FRAME_COMPRESSIONS)}, got {compression!r}"
    )


@dataclass(frozen=True)
class CameraLayout:
    """The camera stream: 8-bit grey frames of a fixed size, one frame per HDF5 chunk."""

    height_px: int
    width_px: int
    frame_rate_hz: float = 60.0
    compression: FrameCompression = "gzip"


@dataclass(frozen=True)
class RunDescription:
    """What is known about a run when it starts (stored once, before SWMR begins)."""

    protocol: str
    parameters: dict[str, Any] = field(default_factory=dict)
    operator: str = ""
    notes: str = ""
    config_toml: str = ""
    calibration: dict[str, Any] = field(default_factory=dict)
    metadata: dict[str, str] = field(default_factory=dict)
    """Key/value pairs exported as ``# key: value`` CSV comment lines (kept verbatim)."""


def now_iso() -> str:
    """The current time as ISO 8601 with the local UTC offset, microsecond resolution."""
    return datetime.now(UTC).astimezone().isoformat(timespec="microseconds")


def software_versions() -> dict[str, str]:
    """Versions of everything that shapes the file's content."""
    try:
        rigctl_version = importlib_metadata.version("rigctl")
    except importlib_metadata.PackageNotFoundError:
        rigctl_version = "unknown"
    return {
        "rigctl": rigctl_version,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "h5py": h5py.version.version,
        "hdf5": h5py.version.hdf5_version,
        "platform": sys.platform,
    }


def fit_utf8(text: str, n_bytes: int) -> bytes:
    """``text`` as UTF-8 in at most ``n_bytes``; a cut is marked with :data:`TRUNCATION_MARK`."""
    raw = text.encode("utf-8")
    if len(raw) <= n_bytes:
        return raw
    mark = TRUNCATION_MARK.encode("utf-8")
    cut = raw[: n_bytes - len(mark)]
    return cut.decode("utf-8", errors="ignore").encode("utf-8") + mark


def fixed_utf8(n_bytes: int) -> np.dtype[Any]:
    """HDF5 fixed-length UTF-8 string type of ``n_bytes`` bytes."""
    return h5py.string_dtype("utf-8", length=n_bytes)


def as_text(value: object) -> str:
    """A string read back from HDF5 (bytes, numpy bytes or str) as ``str``."""
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.shape == ():
        return as_text(value[()])
    return str(value)
