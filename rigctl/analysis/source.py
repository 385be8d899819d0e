"""Open a run for analysis: its samples, what the file says about it, and what is missing.

A run is an HDF5 run file (docs/run-file.md) or an exchange-format CSV (another rig, no frames).
:func:`open_source` reads the samples (SWMR: a run still being written is read up to its last
flushed sample) and checks the camera stream without loading it: frames are streamed later
(:mod:`rigctl.records.contact_frames`). Whatever cannot be analysed is said in :attr:`RunSource.notes`
(one sentence each), never raised as a traceback: no frames, frames without times, a run that did
not close (a recorder killed by SIGKILL leaves ``status = running``). Files that cannot be read at
all raise :class:`rigctl.data.DataError` with one line naming the file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rigctl.data import DataError, FloatArray, MeasuredRun
from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES
from rigctl.io.plausibility import check_plausible
from rigctl.records.delta_stitch import stitch_run
from rigctl.status import RunStatus
from rigctl.storage import layout
from rigctl.storage.reader import RunEvent, RunReader

IMAGE_ANALYSES: tuple[str, ...] = (
    "Isum(t) and its repeatability",
    "I(x,t) and P(x,t)",
    "P at chosen Ft and P in 10 bins",
    "Im(i)",
    "contact spots (WSM) and CSI",
)
"""What needs camera frames (named in the report when a run has none)."""


@dataclass(frozen=True)
class FrameInfo:
    """The camera stream of a run file, without its pixels."""

    n_frames: int
    """Frames that have a time stamp (the ones analysed)."""
    height_px: int
    width_px: int
    t_s: FloatArray
    """Frame times on the DAQ clock (s since the run start)."""
    frame_rate_hz: float
    """The recorded frame rate attribute (NaN if absent)."""

    @property
    def measured_rate_hz(self) -> float:
        """Median frame rate from the time stamps (NaN with fewer than two frames)."""
        if self.t_s.shape[0] < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.t_s)))


@dataclass
class RunSource:
    """A run opened for analysis."""

    path: Path
    run: MeasuredRun
    kind: str
    """'h5' or 'csv'."""
    protocol: str = ""
    parameters: dict[str, Any] = field(default_factory=dict)
    status: str = ""
    """Run-file status (completed, aborted, failed, running); '' for CSV."""
    markers: list[RunEvent] = field(default_factory=list)
    """Protocol step markers of a run file."""
    frames: FrameInfo | None = None
    """None when the run has no usable frames (see notes)."""
    config_toml: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.path.stem


def _frame_info(f: h5py.File, notes: list[str]) -> FrameInfo | None:
    if layout.CAMERA not in f:
        notes.append("the run has no camera stream: " + ", ".join(IMAGE_ANALYSES) + " not done")
        return None
    cam = f[layout.CAMERA]
    if "frames" not in cam:
        notes.append("the camera group has no frames: image analyses not done")
        return None
    frames = cam["frames"]
    if frames.ndim != 3 or frames.dtype != np.uint8:
        notes.append(f"camera frames have shape {frames.shape} / {frames.dtype}, expected "
                     "(k, H, W) uint8: image analyses not done")
        return None
    n_raw = int(frames.shape[0])
    n_time = int(cam["time"].shape[0]) if "time" in cam else 0
    if n_raw == 0:
        notes.append("the run recorded no camera frames: " + ", ".join(IMAGE_ANALYSES)
                     + " not done")
        return None
    if n_time == 0:
        notes.append(f"the run has {n_raw} frames but no frame times: image analyses not done "
                     "(frames cannot be placed on the force record)")
        return None
    n = min(n_raw, n_time)
    t = np.asarray(cam["time"][:n], dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        n = int(bad[0])
        t = t[:n]
        notes.append(f"frame times are not finite from frame {n} on: frames analysed up to it")
    steps = np.diff(t)
    if steps.size and np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        notes.append(f"frame times stop increasing at frame {k}: frames analysed up to it")
        n, t = k, t[:k]
    if n < n_raw and n_time < n_raw:
        notes.append(f"{n_raw - n_time} of {n_raw} frames have no time stamp (a run cut "
                     "while recording): they are not analysed")
    if n < 2:
        notes.append("fewer than two timed frames: image analyses not done")
        return None
    rate = float(cam.attrs.get("frame_rate_hz", float("nan")))
    return FrameInfo(n, int(frames.shape[1]), int(frames.shape[2]), t, rate)


MIN_SAMPLES = 64
"""Fewer samples than this are nothing to analyse."""


def _usable(run: MeasuredRun, path: Path) -> list[str]:
    """DataError for a run too short to analyse or with values no rig measures (the readers' one
    plausibility check, :func:`rigctl.io.plausibility.check_plausible`); its warnings otherwise."""
    if run.n_samples < MIN_SAMPLES:
        raise DataError(f"the run has only {run.n_samples} sample(s): nothing to analyse "
                        f"(at least {MIN_SAMPLES})", path=path)
    return check_plausible(run, path.name)


def _open_h5(path: Path) -> RunSource:
    """A run file; a damaged one is read as far as it holds data (RunReader says what is left
    out), or refused in one line."""
    notes: list[str] = []
    try:
        with RunReader(path) as reader:
            status = reader.status
            run = reader.to_measured(validate=True)
            notes += _usable(run, path)
            try:
                parameters = reader.parameters
            except (KeyError, json.JSONDecodeError):
                parameters = {}
                notes.append("protocol parameters unreadable")
            markers = reader.events()
            run = stitch_run(run, markers)  # delta continuous across the probes' re-centrings
            frames = _frame_info(reader.h5file, notes)
            protocol = reader.protocol
            config = reader.config_toml
    except (OSError, KeyError, TypeError) as exc:
        raise DataError(f"the run file is damaged or incomplete ({type(exc).__name__}: {exc})",
                        path=path) from exc
    if status == RunStatus.RUNNING:
        notes.insert(0, f"the run did not close (status 'running': still being recorded, or the "
                        f"recorder was killed); analysed up to its last flushed sample, "
                        f"t = {run.t_s[-1]:.2f} s")
    elif status in (RunStatus.ABORTED, RunStatus.FAILED):
        notes.insert(0, f"the run was {status}: analysed as far as it went")
    return RunSource(path, run, "h5", protocol, parameters, status, markers, frames, config, notes)


def open_source(path: str | Path) -> RunSource:
    """Open one run file or CSV for analysis (DataError if it cannot be read at all)."""
    p = Path(path)
    if not p.is_file():
        raise DataError("no such file", path=p)
    suffix = p.suffix.lower()
    if suffix in RUN_FILE_SUFFIXES:
        return _open_h5(p)
    if suffix in CSV_SUFFIXES:
        from rigctl.io.csv_format import read_csv

        run = read_csv(p)
        run.validate()
        notes = _usable(run, p)
        notes.append("a CSV run has no camera frames: " + ", ".join(IMAGE_ANALYSES) + " not done")
        return RunSource(p, run, "csv", run.metadata.get("protocol", ""), {}, "", [], None, "",
                         notes)
    raise DataError(f"unknown file type {p.suffix!r}: expected .h5 or .csv", path=p)
