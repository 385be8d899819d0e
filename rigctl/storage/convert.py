"""Make a run file from a :class:`MeasuredRun` (``rigctl import``, ``rigctl simulate --out``).

The file is written under a temporary name in the target folder and renamed into place when it is
complete, so an import that fails half-way leaves nothing behind. Its layout is exactly that of a
recorded run (the same :class:`RunWriter` writes it): the required columns and every extra column
become DAQ channels, ``run.metadata`` becomes ``/entry/metadata``; a CSV exported from it is the
CSV it came from.
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
from typing import Any

from rigctl.data import MeasuredRun
from rigctl.storage import layout
from rigctl.storage.errors import StorageError
from rigctl.storage.preflight import DEFAULT_MIN_FREE_BYTES, check_output_path, estimate_run_bytes
from rigctl.storage.writer import RunWriter

_BLOCK = 65536


def write_measured_run(
    path: str | Path,
    run: MeasuredRun,
    *,
    protocol: str = "import",
    parameters: dict[str, Any] | None = None,
    operator: str = "",
    notes: str = "",
    config_toml: str = "",
    calibration: dict[str, Any] | None = None,
    overwrite: bool = False,
    min_free_bytes: int = DEFAULT_MIN_FREE_BYTES,
    status: layout.RunStatus = layout.RunStatus.COMPLETED,
    error: str | None = None,
) -> Path:
    """Write ``run`` (validated first) as a closed run file at ``path`` with ``status`` (default
    completed; an import of an aborted run keeps its status); returns the path."""
    target = Path(path)
    run.validate()
    channels = tuple(name for name in run.columns() if name != "t_s")
    daq = layout.DaqLayout(channels=channels, sample_rate_hz=_sample_rate_hz(run))
    check_output_path(
        target,
        required_bytes=estimate_run_bytes(run.duration_s, daq),
        min_free_bytes=min_free_bytes,
        overwrite=overwrite,
    )
    description = layout.RunDescription(
        protocol=protocol,
        parameters=dict(parameters or {}),
        operator=operator or run.metadata.get("operator", ""),
        notes=notes,
        config_toml=config_toml,
        calibration=dict(calibration or {}),
        metadata=dict(run.metadata),
    )
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        with RunWriter(tmp, description, daq, min_free_bytes=0, overwrite=True) as writer:
            columns = run.columns()
            for start in range(0, run.n_samples, _BLOCK):
                writer.append_daq({k: v[start : start + _BLOCK] for k, v in columns.items()})
            writer.close(status, error)
        os.replace(tmp, target)
    except OSError as exc:
        raise StorageError(f"cannot write the run file: {exc}", path=target) from exc
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    return target


def _sample_rate_hz(run: MeasuredRun) -> float:
    """The declared ``sample_rate_hz`` metadata if usable, else the median rate of the time base."""
    declared = run.metadata.get("sample_rate_hz", "")
    try:
        value = float(declared)
    except ValueError:
        value = math.nan
    if math.isfinite(value) and value > 0:
        return value
    measured = run.sample_rate_hz
    return measured if math.isfinite(measured) and measured > 0 else 1.0


__all__ = ["write_measured_run"]
