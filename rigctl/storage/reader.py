"""Read run files (docs/run-file.md), including one another process is still writing.

Files are opened with ``swmr=True``: that reads a finished file, follows a file being written (call
:meth:`RunReader.refresh` to see new samples), and opens a file whose writer was killed (its
"file open for writing" flag is still set, which a plain open refuses). Files written by other tools
in the pre-1.10 format cannot be opened for SWMR; they are opened normally.

While a file grows, the datasets of one stream can momentarily differ in length (the writer resizes
them one after another): the reader reports the length all of them have reached.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import h5py
import numpy as np

from rigctl.data import REQUIRED_COLUMNS, DataError, FloatArray, MeasuredRun
from rigctl.storage import layout

_log = logging.getLogger(__name__)


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
        self._truncation = _check_not_truncated(self.path)
        self._file = _open(self.path)
        try:
            self._check_layout()
        except BaseException:
            self._file.close()
            raise
        if self._truncation:
            _log.warning("%s: %s; reading what is there", self.path, self._truncation)
        daq = self._file[layout.DAQ]
        names = [layout.as_text(n) for n in daq.attrs["channels"]]
        self._channels: dict[str, h5py.Dataset] = {name: daq[name] for name in names}
        self._time: h5py.Dataset = daq["time"]

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

    def refresh(self) -> int:
        """Take in what the writer has flushed since the last look; returns :attr:`n_samples`."""
        if self._file.swmr_mode:
            for obj in self._growing_datasets():
                obj.refresh()
        return self.n_samples

    def _growing_datasets(self) -> list[h5py.Dataset]:
        e = self._file[layout.ENTRY]
        found = [self._time, *self._channels.values(), e["status"], e["end_time"], e["error"]]
        found += [self._file[layout.DAQ_BLOCKS][k] for k in self._file[layout.DAQ_BLOCKS]]
        found += [self._file[layout.EVENTS][k] for k in self._file[layout.EVENTS]]
        if layout.CAMERA in self._file:
            found += [self._file[layout.CAMERA][k] for k in self._file[layout.CAMERA]]
        return found

    # -- samples -----------------------------------------------------------------------------------

    @property
    def h5file(self) -> h5py.File:
        """The open file (read-only), for what the reader does not wrap (the camera frames)."""
        return self._file

    @property
    def channels(self) -> dict[str, str]:
        """Channel name -> unit, in recording order."""
        return {
            name: layout.as_text(ds.attrs.get("units", "")) for name, ds in self._channels.items()
        }

    @property
    def n_samples(self) -> int:
        """Samples present in every DAQ dataset."""
        return min(ds.shape[0] for ds in (self._time, *self._channels.values()))

    def unequal_lengths(self) -> dict[str, int]:
        """The DAQ datasets' lengths when they differ in a closed run (empty otherwise): a run being
        written grows them one after another, a closed one has them equal unless it is damaged."""
        lengths = {ds.name: int(ds.shape[0]) for ds in (self._time, *self._channels.values())}
        if len(set(lengths.values())) <= 1 or self.status == "running":
            return {}
        return lengths

    @property
    def sample_rate_hz(self) -> float:
        return float(self._file[layout.DAQ].attrs["sample_rate_hz"])

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
        except OSError as exc:
            first = exc
        # locate the damaged chunk for the message
        step = ds.chunks[0] if ds.chunks else max(stop - start, 1)
        bad = (start, stop)
        for a in range(start - start % step, stop, step):
            try:
                ds[max(a, start) : min(a + step, stop)]
            except OSError:
                bad = (max(a, start), min(a + step, stop))
                break
        what = ("checksum mismatch (the file is corrupted)" if ds.fletcher32
                else f"unreadable ({first})")
        raise DataError(f"{ds.name}: samples {bad[0]:,} to {bad[1]:,}: {what}", path=self.path)

    def blocks(self) -> dict[str, np.ndarray]:
        """The per-block table for re-timing: ``first_sample``, ``counter``, ``host_time_s``,
        ``dropped`` (equal-length arrays, one row per block the writer received)."""
        g = self._file[layout.DAQ_BLOCKS]
        n = min(g[k].shape[0] for k in ("first_sample", "counter", "host_time", "dropped"))
        return {
            "first_sample": np.asarray(g["first_sample"][:n], dtype=np.int64),
            "counter": np.asarray(g["counter"][:n], dtype=np.int64),
            "host_time_s": np.asarray(g["host_time"][:n], dtype=np.float64),
            "dropped": np.asarray(g["dropped"][:n], dtype=np.int64),
        }

    def to_measured(self, *, validate: bool = True) -> MeasuredRun:
        """The run as a :class:`MeasuredRun` (required channels + the others as extras).

        ``metadata`` is exactly the file's ``/entry/metadata`` (a CSV export writes it back as
        ``# key: value`` lines). With ``validate`` a NaN or a non-increasing time raises
        :class:`DataError`.
        """
        uneven = self.unequal_lengths()
        if uneven:
            _log.warning("%s: DAQ datasets of unequal length in a closed run (%s): read to the "
                         "shortest, %s samples", self.path,
                         ", ".join(f"{k} {v:,}" for k, v in uneven.items()), f"{self.n_samples:,}")
        columns = self.read_daq()
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
        return layout.as_text(self._file[layout.ENTRY][name][()])

    @property
    def status(self) -> str:
        """``running`` (still being written, or the writer died), ``completed``, ``aborted``,
        ``failed``."""
        return self._text("status")

    @property
    def metadata(self) -> dict[str, str]:
        text = layout.as_text(self._file[layout.METADATA][()])
        return {str(k): str(v) for k, v in json.loads(text).items()}

    @property
    def protocol(self) -> str:
        return layout.as_text(self._file[layout.ENTRY]["protocol/name"][()])

    @property
    def parameters(self) -> dict[str, Any]:
        return dict(json.loads(layout.as_text(self._file[layout.ENTRY]["protocol/parameters"][()])))

    @property
    def calibration(self) -> dict[str, Any]:
        return dict(json.loads(self._text("calibration")))

    @property
    def config_toml(self) -> str:
        return layout.as_text(self._file[layout.ENTRY]["config/data"][()])

    @property
    def software(self) -> dict[str, str]:
        group = self._file[layout.ENTRY]["software"]
        return {k: layout.as_text(group[k][()]) for k in group}

    def events(self) -> list[RunEvent]:
        ev = self._file[layout.EVENTS]
        n = min(ev[k].shape[0] for k in ("time", "name", "message"))
        times = ev["time"][:n]
        names = ev["name"][:n]
        messages = ev["message"][:n]
        return [
            RunEvent(float(t), layout.as_text(a), layout.as_text(b))
            for t, a, b in zip(times, names, messages, strict=True)
        ]

    @property
    def n_frames(self) -> int:
        if layout.CAMERA not in self._file:
            return 0
        cam = self._file[layout.CAMERA]
        return min(cam[k].shape[0] for k in ("frames", "time", "seq"))

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

    def dropped_samples(self) -> int:
        """Samples the DAQ counter says were lost (sum over blocks)."""
        return int(np.sum(self._file[layout.DAQ_BLOCKS]["dropped"][:]))

    def dropped_frames(self) -> int:
        """Frames missing from the camera sequence numbers (gaps)."""
        if layout.CAMERA not in self._file:
            return 0
        seq = np.asarray(self._file[layout.CAMERA]["seq"][: self.n_frames], dtype=np.int64)
        return int(np.sum(np.clip(np.diff(seq) - 1, 0, None))) if seq.size > 1 else 0

    def summary(self) -> RunSummary:
        n = self.n_samples
        t = self._time[[0, n - 1]] if n >= 2 else np.zeros(2)
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
            duration_s=float(t[1] - t[0]),
            sample_rate_hz=self.sample_rate_hz,
            channels=self.channels,
            dropped_samples=self.dropped_samples(),
            n_events=min(
                self._file[layout.EVENTS][k].shape[0] for k in ("time", "name", "message")
            ),
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
            raise DataError(f"not a rigctl run file (definition {definition!r})"
                            + self._truncation_note(), path=self.path)
        daq = f[layout.DAQ]
        absent = [name for name in map(layout.as_text, daq.attrs["channels"]) if name not in daq]
        if absent:
            raise DataError(
                f"the run lists channel(s) {', '.join(absent)} but has no "
                f"{', '.join(f'{layout.DAQ}/{a}' for a in absent)} dataset (a damaged or "
                "hand-edited file)", path=self.path)

    def _truncation_note(self) -> str:
        """``"; truncated file: ..."`` for an error about a file that was let through truncated."""
        return f"; {self._truncation}" if self._truncation else ""


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _declared_size(head: bytes) -> int | None:
    """The end-of-file address an HDF5 superblock at offset 0 declares (None if not readable).

    Superblock layouts (HDF5 file format specification, "Superblock", versions 0-3): the EOF
    address follows the base and the free-space/extension addresses, each ``size of offsets``
    bytes: at 24 + 2 so (version 0), 28 + 2 so (version 1), 12 + 2 so (versions 2 and 3).
    """
    if len(head) < 16 or not head.startswith(HDF5_SIGNATURE):
        return None
    version = head[8]
    if version in (0, 1):
        so = head[13]
        at = (24 if version == 0 else 28) + 2 * so
    elif version in (2, 3):
        so = head[9]
        at = 12 + 2 * so
    else:
        return None
    if so not in (2, 4, 8) or len(head) < at + so:
        return None
    return int.from_bytes(head[at : at + so], "little")


def _check_not_truncated(path: Path) -> str | None:
    """Refuse a file shorter than its header says, before HDF5 sees it: a SWMR open of such a file
    retries its metadata reads for minutes, ignoring Ctrl-C (a plain open says 'truncated file'
    but cannot follow a file being written). A file being written keeps its declared end equal to
    its size (measured on live run files), so this never refuses one. A truncated file that opens
    in a child process within :data:`TRUNCATED_OPEN_TIMEOUT_S` (a disk that filled mid-run) is
    let through (the reader warns); the returned note ("truncated file: ...") then goes into any later
    error about the file, else None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
        size = path.stat().st_size
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from None
    if head and not head.startswith(HDF5_SIGNATURE):
        raise DataError("not an HDF5 file (no HDF5 signature at its start)", path=path)
    if len(head) < 16:
        raise DataError(f"truncated file: only {size:,} bytes, not even an HDF5 header", path=path)
    declared = _declared_size(head)
    if declared is None or size >= declared:
        return None
    note = f"truncated file: {size:,} bytes of the {declared:,} its header declares"
    if _swmr_opens_within(path, TRUNCATED_OPEN_TIMEOUT_S):
        return note  # e.g. a run whose disk filled: what was flushed before the cut reads normally
    raise DataError(f"{note} (a copy cut short or a damaged disk; the data cannot be read)",
                    path=path)


TRUNCATED_OPEN_TIMEOUT_S = 5.0
"""How long a truncated file may take to open (in a child process, killed after it): a file cut
after its flushed part (a full disk) opens at once; one cut inside its metadata makes HDF5 retry
for tens of minutes."""


def _swmr_opens_within(path: Path, timeout_s: float) -> bool:
    """Whether a SWMR open of ``path`` and a walk of all its objects (every metadata read a reader
    makes) succeed within ``timeout_s``: tried in a child process, killed on timeout, since the
    HDF5 library's retries cannot be interrupted in-process."""
    code = ("import sys, h5py\n"
            "with h5py.File(sys.argv[1], 'r', swmr=True) as f:\n"
            "    f.visititems(lambda name, obj: obj.shape if hasattr(obj, 'shape') else None)\n")
    try:
        proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                              timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired:
        return False
    return proc.returncode == 0


def _open(path: Path) -> h5py.File:
    """Open read-only, SWMR when the file allows it (see the module docstring); the caller has
    checked for truncation (:func:`_check_not_truncated`)."""
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError as swmr_exc:
        try:
            return h5py.File(path, "r")
        except OSError:
            raise DataError(f"cannot open as HDF5: {swmr_exc}", path=path) from swmr_exc


def read_run(path: str | Path, *, validate: bool = True) -> MeasuredRun:
    """The samples of a run file as a :class:`MeasuredRun` (see :meth:`RunReader.to_measured`)."""
    with RunReader(path) as reader:
        return reader.to_measured(validate=validate)
