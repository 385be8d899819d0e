"""Read run files (docs/run-file.md), including one another process is still writing.

Files are opened with ``swmr=True``: that reads a finished file, follows a file being written (call
:meth:`RunReader.refresh` to see new samples), and opens a file whose writer was killed (its
"file open for writing" flag is still set, which a plain open refuses). Files written by other tools
in the pre-1.10 format cannot be opened for SWMR; they are opened normally.

While a file grows, the datasets of one stream can momentarily differ in length (the writer resizes
them one after another): the reader reports the length all of them have reached.

A damaged file never hangs a reader and never gives a traceback (docs/reliability.md, "Files"): it
is opened by :func:`rigctl.storage.safe_open.open_run_file` (its metadata checked first, in a
killable child process when needed), any later failure of the HDF5 library is a one-line
:class:`DataError`, and rows a file counts but does not hold (a disk that filled, a copy cut short)
are left out with a warning naming them (:mod:`rigctl.storage.valid_rows`).
"""

from __future__ import annotations

import functools
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Concatenate, ParamSpec, TypeVar

import h5py
import numpy as np

from rigctl.data import REQUIRED_COLUMNS, DataError, FloatArray, MeasuredRun
from rigctl.storage import layout
from rigctl.storage.safe_open import open_run_file
from rigctl.storage.text import one_line, printable
from rigctl.storage.valid_rows import increasing_prefix, rows_in_file

_log = logging.getLogger(__name__)

_P = ParamSpec("_P")
_T = TypeVar("_T")

_LIBRARY_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError)
"""What h5py (and decoding a damaged field) raises on a damaged file."""


def _guarded(method: Callable[Concatenate[RunReader, _P], _T]) -> Callable[Concatenate[RunReader, _P], _T]:
    """A failure of the library while reading is a one-line DataError naming the file."""

    @functools.wraps(method)
    def wrapper(self: RunReader, *args: _P.args, **kwargs: _P.kwargs) -> _T:
        try:
            return method(self, *args, **kwargs)
        except DataError:
            raise
        except _LIBRARY_ERRORS as exc:
            raise DataError(f"damaged run file ({method.__name__}: {one_line(exc)})"
                            + self._truncation_note(), path=self.path) from None

    return wrapper


@dataclass(frozen=True)
class RunEvent:
    """A protocol step marker."""

    t_s: float
    name: str
    message: str


@dataclass(frozen=True)
class RunSummary:
    """What ``rigctl info`` shows about a run."""

    path: str
    protocol: str
    parameters: dict[str, Any]
    status: str
    error: str
    start_time: str
    end_time: str
    operator: str
    notes: str
    n_samples: int
    duration_s: float
    sample_rate_hz: float
    channels: dict[str, str]
    dropped_samples: int
    n_events: int
    n_frames: int
    dropped_frames: int
    software: dict[str, str] = field(default_factory=dict)


class RunReader:
    """Read access to one run file; a context manager (closes the file)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise DataError("no such file", path=self.path)
        opened = open_run_file(self.path)
        self._file = opened.file
        self._truncation = opened.truncation
        self._caps: dict[str, int] = {}
        try:
            self._check_layout()
            daq = self._file[layout.DAQ]
            names = [layout.as_text(n) for n in daq.attrs["channels"]]
            self._channels: dict[str, h5py.Dataset] = {name: daq[name] for name in names}
            self._time: h5py.Dataset = daq["time"]
            self._rows_valid: h5py.Dataset | None = self._file.get(layout.ROWS_VALID)
            if not self._file.swmr_mode or self._truncation:  # a file that no longer grows
                self._caps = {ds.name: rows_in_file(ds, opened.size_bytes)
                              for ds in self._growing_datasets() if ds.chunks is not None}
            self._warn_rows_left_out()
        except BaseException as exc:
            self._file.close()
            if isinstance(exc, _LIBRARY_ERRORS) and not isinstance(exc, DataError):
                raise DataError(f"damaged run file: {one_line(exc)}" + self._truncation_note(),
                                path=self.path) from None
            raise

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> RunReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- live following --------------------------------------------------------------------------

    @_guarded
    def refresh(self) -> int:
        """Take in what the writer has flushed since the last look; returns :attr:`n_samples`."""
        if self._file.swmr_mode:
            for obj in self._growing_datasets():
                obj.refresh()
            if self._rows_valid is not None:
                self._rows_valid.refresh()
            e = self._file[layout.ENTRY]
            for name in ("status", "end_time", "error"):
                e[name].refresh()
        return self.n_samples

    def _growing_datasets(self) -> list[h5py.Dataset]:
        found = [self._time, *self._channels.values()]
        for group in (layout.DAQ_BLOCKS, layout.EVENTS, layout.CAMERA):
            if group in self._file:
                found += [self._file[group][k] for k in self._file[group]]
        return found

    def _rows(self, ds: h5py.Dataset) -> int:
        """Rows of a growing dataset that the file holds (its length, less a lost tail)."""
        n = int(ds.shape[0])
        return min(n, self._caps.get(ds.name, n))

    def _warn_rows_left_out(self) -> None:
        """Say once, at open, which counted rows are not in the file and are left out."""
        counted = min(int(ds.shape[0]) for ds in (self._time, *self._channels.values()))
        held = self.n_samples
        if held < counted:
            why = self._truncation or "their data were never written (a disk that filled?)"
            _log.warning("%s: %s; samples %s to %s are not in the file and are left out: reading "
                         "the %s before them", self.path, why, f"{held:,}", f"{counted:,}",
                         f"{held:,}")
        elif self._truncation:
            _log.warning("%s: %s; every sample is there, reading it", self.path, self._truncation)

    # -- samples -----------------------------------------------------------------------------------

    @property
    def h5file(self) -> h5py.File:
        """The open file (read-only), for what the reader does not wrap (the camera frames)."""
        return self._file

    @property
    @_guarded
    def channels(self) -> dict[str, str]:
        """Channel name -> unit, in recording order."""
        return {
            name: printable(layout.as_text(ds.attrs.get("units", "")))
            for name, ds in self._channels.items()
        }

    @property
    @_guarded
    def n_samples(self) -> int:
        """Samples present in every DAQ dataset (and, in files of format 1.1, known written)."""
        n = min(self._rows(ds) for ds in (self._time, *self._channels.values()))
        if self._rows_valid is not None:
            n = min(n, max(int(self._rows_valid[0]), 0))
        return n

    def unequal_lengths(self) -> dict[str, int]:
        """The DAQ datasets' lengths when they differ in a closed run (empty otherwise): a run being
        written grows them one after another, a closed one has them equal unless it is damaged."""
        lengths = {ds.name: self._rows(ds) for ds in (self._time, *self._channels.values())}
        if len(set(lengths.values())) <= 1 or self.status == "running" or self._caps_cut():
            return {}
        return lengths

    def _caps_cut(self) -> bool:
        """Whether rows were left out as not in the file (said at open)."""
        return any(self._caps.get(ds.name, ds.shape[0]) < ds.shape[0]
                   for ds in (self._time, *self._channels.values()))

    @property
    @_guarded
    def sample_rate_hz(self) -> float:
        return float(self._file[layout.DAQ].attrs["sample_rate_hz"])

    @_guarded
    def read_daq(self, start: int = 0, stop: int | None = None) -> dict[str, FloatArray]:
        """Samples ``start:stop`` (default all) as ``{"t_s": ..., channel: ...}`` float64 arrays."""
        n = self.n_samples
        stop = n if stop is None else min(stop, n)
        out: dict[str, FloatArray] = {"t_s": self._read(self._time, start, stop)}
        for name, ds in self._channels.items():
            out[name] = self._read(ds, start, stop)
        return out

    def _read(self, ds: h5py.Dataset, start: int, stop: int) -> FloatArray:
        """``ds[start:stop]`` as float64; a chunk whose checksum fails (the writer stores a
        Fletcher-32 checksum per chunk) or cannot be read is a DataError naming the dataset and
        the sample range of the read."""
        try:
            return np.asarray(ds[start:stop], dtype=np.float64)
        except (OSError, RuntimeError) as exc:
            first = exc
        # locate the damaged chunk for the message
        step = ds.chunks[0] if ds.chunks else max(stop - start, 1)
        bad = (start, stop)
        for a in range(start - start % step, stop, step):
            try:
                ds[max(a, start) : min(a + step, stop)]
            except (OSError, RuntimeError):
                bad = (max(a, start), min(a + step, stop))
                break
        what = ("checksum mismatch (the file is corrupted)" if ds.fletcher32
                else f"unreadable ({one_line(first)})")
        readable = f"; samples before {bad[0]:,} read" if bad[0] > 0 else ""
        raise DataError(f"{ds.name}: samples {bad[0]:,} to {bad[1]:,}: {what}{readable}"
                        + self._truncation_note(), path=self.path)

    @_guarded
    def valid_samples(self) -> int:
        """:attr:`n_samples`, ended before the first time that is not finite and increasing (the
        writer stores no such time: it is a part of the file that was never written), with a
        warning naming the samples left out."""
        n = self.n_samples
        k = increasing_prefix(self._read(self._time, 0, n))
        if k < n:
            _log.warning("%s: time is not increasing from sample %s on (rows counted but never "
                         "written, e.g. a disk that filled): samples %s to %s left out, reading "
                         "the %s before them", self.path, f"{k:,}", f"{k:,}", f"{n:,}", f"{k:,}")
        return k

    @_guarded
    def blocks(self) -> dict[str, np.ndarray]:
        """The per-block table for re-timing: ``first_sample``, ``counter``, ``host_time_s``,
        ``dropped`` (equal-length arrays, one row per block the writer received)."""
        g = self._file[layout.DAQ_BLOCKS]
        n = self._n_blocks()
        return {
            "first_sample": np.asarray(g["first_sample"][:n], dtype=np.int64),
            "counter": np.asarray(g["counter"][:n], dtype=np.int64),
            "host_time_s": np.asarray(g["host_time"][:n], dtype=np.float64),
            "dropped": np.asarray(g["dropped"][:n], dtype=np.int64),
        }

    def _n_blocks(self) -> int:
        g = self._file[layout.DAQ_BLOCKS]
        n = min(self._rows(g[k]) for k in ("first_sample", "counter", "host_time", "dropped"))
        if self._rows_valid is not None:
            n = min(n, max(int(self._rows_valid[1]), 0))
        return n

    @_guarded
    def to_measured(self, *, validate: bool = True) -> MeasuredRun:
        """The run as a :class:`MeasuredRun` (required channels + the others as extras).

        ``metadata`` is exactly the file's ``/entry/metadata`` (a CSV export writes it back as
        ``# key: value`` lines). Rows the file counts but never wrote are left out with a warning
        (:meth:`valid_samples`). With ``validate`` a NaN or a non-increasing time raises
        :class:`DataError`.
        """
        uneven = self.unequal_lengths()
        if uneven:
            _log.warning("%s: DAQ datasets of unequal length in a closed run (%s): read to the "
                         "shortest, %s samples", self.path,
                         ", ".join(f"{k} {v:,}" for k, v in uneven.items()), f"{self.n_samples:,}")
        columns = self.read_daq(0, self.valid_samples())
        missing = [name for name in REQUIRED_COLUMNS if name not in columns]
        if missing:
            raise DataError(
                f"the run has no channel(s) {', '.join(missing)} (it has "
                f"{', '.join(self._channels)})",
                path=self.path,
                column=missing[0],
            )
        run = MeasuredRun(
            **{name: columns[name] for name in REQUIRED_COLUMNS},
            extra={k: v for k, v in columns.items() if k not in REQUIRED_COLUMNS},
            metadata=self.metadata,
            source=str(self.path),
        )
        if validate:
            run.validate()
        return run

    # -- descriptive fields ------------------------------------------------------------------------

    def _text(self, name: str) -> str:
        return printable(layout.as_text(self._file[layout.ENTRY][name][()]))

    @property
    @_guarded
    def status(self) -> str:
        """``running`` (still being written, or the writer died), ``completed``, ``aborted``,
        ``failed``."""
        return self._text("status")

    @property
    @_guarded
    def metadata(self) -> dict[str, str]:
        text = layout.as_text(self._file[layout.METADATA][()])
        return {printable(str(k)): printable(str(v)) for k, v in json.loads(text).items()}

    @property
    @_guarded
    def protocol(self) -> str:
        return self._text("protocol/name")

    @property
    @_guarded
    def parameters(self) -> dict[str, Any]:
        return dict(json.loads(layout.as_text(self._file[layout.ENTRY]["protocol/parameters"][()])))

    @property
    @_guarded
    def calibration(self) -> dict[str, Any]:
        return dict(json.loads(layout.as_text(self._file[layout.ENTRY]["calibration"][()])))

    @property
    @_guarded
    def config_toml(self) -> str:
        return printable(layout.as_text(self._file[layout.ENTRY]["config/data"][()]),
                         keep_lines=True)

    @property
    @_guarded
    def software(self) -> dict[str, str]:
        group = self._file[layout.ENTRY]["software"]
        return {k: printable(layout.as_text(group[k][()])) for k in group}

    @_guarded
    def events(self) -> list[RunEvent]:
        ev = self._file[layout.EVENTS]
        n = self._n_events()
        times = ev["time"][:n]
        names = ev["name"][:n]
        messages = ev["message"][:n]
        return [
            RunEvent(float(t), printable(layout.as_text(a)), printable(layout.as_text(b)))
            for t, a, b in zip(times, names, messages, strict=True)
        ]

    def _n_events(self) -> int:
        ev = self._file[layout.EVENTS]
        return min(self._rows(ev[k]) for k in ("time", "name", "message"))

    @property
    @_guarded
    def n_frames(self) -> int:
        if layout.CAMERA not in self._file:
            return 0
        cam = self._file[layout.CAMERA]
        return min(self._rows(cam[k]) for k in ("frames", "time", "seq"))

    @_guarded
    def frames(
        self, start: int = 0, stop: int | None = None
    ) -> tuple[np.ndarray, FloatArray, np.ndarray]:
        """Frames ``start:stop`` as ``(frames (k, H, W) uint8, t_s (k,), seq (k,))``."""
        if layout.CAMERA not in self._file:
            return np.empty((0, 0, 0), np.uint8), np.empty(0), np.empty(0, np.int64)
        n = self.n_frames
        stop = n if stop is None else min(stop, n)
        cam = self._file[layout.CAMERA]
        return (
            np.asarray(cam["frames"][start:stop]),
            np.asarray(cam["time"][start:stop], dtype=np.float64),
            np.asarray(cam["seq"][start:stop], dtype=np.int64),
        )

    @_guarded
    def dropped_samples(self) -> int:
        """Samples the DAQ counter says were lost (sum over blocks)."""
        return int(np.sum(self._file[layout.DAQ_BLOCKS]["dropped"][: self._n_blocks()]))

    @_guarded
    def dropped_frames(self) -> int:
        """Frames missing from the camera sequence numbers (gaps)."""
        if layout.CAMERA not in self._file:
            return 0
        seq = np.asarray(self._file[layout.CAMERA]["seq"][: self.n_frames], dtype=np.int64)
        return int(np.sum(np.clip(np.diff(seq) - 1, 0, None))) if seq.size > 1 else 0

    @_guarded
    def summary(self) -> RunSummary:
        """What ``rigctl info`` shows; samples and duration are those of the part of the run that is
        in the file (:meth:`valid_samples`)."""
        n = self.valid_samples()
        duration = 0.0
        if n >= 2:
            duration = float(self._read(self._time, n - 1, n)[0] - self._read(self._time, 0, 1)[0])
        return RunSummary(
            path=str(self.path),
            protocol=self.protocol,
            parameters=self.parameters,
            status=self.status,
            error=self._text("error"),
            start_time=self._text("start_time"),
            end_time=self._text("end_time"),
            operator=self._text("operator"),
            notes=self._text("notes"),
            n_samples=n,
            duration_s=duration,
            sample_rate_hz=self.sample_rate_hz,
            channels=self.channels,
            dropped_samples=self.dropped_samples(),
            n_events=self._n_events(),
            n_frames=self.n_frames,
            dropped_frames=self.dropped_frames(),
            software=self.software,
        )

    def _check_layout(self) -> None:
        f = self._file
        if (
            layout.DAQ not in f
            or "time" not in f[layout.DAQ]
            or "channels" not in f[layout.DAQ].attrs
        ):
            raise DataError(
                "not a rigctl run file (no /entry/daq with time and channels)"
                + self._truncation_note(), path=self.path
            )
        definition = (
            layout.as_text(f[layout.ENTRY]["definition"][()])
            if "definition" in f[layout.ENTRY]
            else ""
        )
        if definition != layout.FORMAT_NAME:
            raise DataError(f"not a rigctl run file (definition {printable(definition)!r})"
                            + self._truncation_note(), path=self.path)
        daq = f[layout.DAQ]
        absent = [name for name in map(layout.as_text, daq.attrs["channels"]) if name not in daq]
        if absent:
            raise DataError(
                f"the run lists channel(s) {printable(', '.join(absent))} but has no "
                f"{printable(', '.join(f'{layout.DAQ}/{a}' for a in absent))} dataset (a damaged "
                "or hand-edited file)", path=self.path)

    def _truncation_note(self) -> str:
        """``"; truncated file: ..."`` for an error about a file that was let through truncated."""
        return f"; {self._truncation}" if self._truncation else ""


def read_run(path: str | Path, *, validate: bool = True) -> MeasuredRun:
    """The samples of a run file as a :class:`MeasuredRun` (see :meth:`RunReader.to_measured`)."""
    with RunReader(path) as reader:
        return reader.to_measured(validate=validate)
