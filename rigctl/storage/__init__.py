"""HDF5 run files: one NeXus-style file per run, written live in SWMR mode (docs/run-file.md)."""

from rigctl.storage.convert import write_measured_run
from rigctl.storage.errors import StorageError
from rigctl.storage.layout import (
    DEFAULT_DAQ_CHANNELS,
    CameraLayout,
    DaqLayout,
    RunDescription,
    unit_of,
)
from rigctl.storage.preflight import check_output_path, estimate_run_bytes
from rigctl.storage.reader import RunEvent, RunReader, RunSummary, read_run
from rigctl.storage.writer import RunWriter

__all__ = [
    "DEFAULT_DAQ_CHANNELS",
    "CameraLayout",
    "DaqLayout",
    "RunDescription",
    "RunEvent",
    "RunReader",
    "RunSummary",
    "RunWriter",
    "StorageError",
    "check_output_path",
    "estimate_run_bytes",
    "read_run",
    "unit_of",
    "write_measured_run",
]
