"""Record one run into an HDF5 file that other processes can read while it grows (SWMR).

:class:`RunWriter` creates every group and dataset of docs/run-file.md first, switches the file to
SWMR mode, and from then on only resizes, writes and flushes, as SWMR requires. Samples are taken in
blocks of any size, coalesced in memory and written in one resize per dataset; the file is flushed
at least every ``flush_interval_s`` (default 0.25 s), so a writer killed with SIGKILL loses at most
that much plus the blocks not yet handed over.

One thread writes. The acquisition layer's writer thread feeds it from its queues and calls
:meth:`RunWriter.maybe_flush` when a queue is idle, so flushes happen on time even without data;
a second thread calling an append method is refused (:class:`RuntimeError`).

While recording, the free space of the file system is checked every ``DISK_CHECK_INTERVAL_S``; when
it falls below half of ``min_free_bytes`` the writer raises :class:`StorageError` ("disk nearly full")
while there is still room to close the file cleanly with its status. A write that fails anyway
(a full disk, an I/O error) leaves the HDF5 library holding a half-closed file; such files are kept
alive by :func:`rigctl.teardown.keep_alive` (never garbage-collected: HDF5 may crash on them), and
the command line leaves the process without the library's teardown (see :func:`rigctl.cli.main.main`).

Used as a context manager, the run's final status is recorded whatever happens: ``completed`` on a
clean exit, ``aborted`` on ``KeyboardInterrupt``, ``failed`` with the exception text otherwise; the
samples already appended are written before the file is closed.
"""

from __future__ import annotations

import json
import shutil
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

import h5py
import numpy as np
from numpy.typing import ArrayLike

from rigctl.data import DataError, FloatArray
from rigctl.storage import layout
from rigctl.storage.errors import StorageError
from rigctl.storage.preflight import DEFAULT_MIN_FREE_BYTES, check_output_path, estimate_run_bytes
from rigctl.storage.text import one_line
from rigctl.teardown import keep_alive

DEFAULT_FLUSH_INTERVAL_S = 0.25
MAX_FLUSH_INTERVAL_S = 0.5
_COALESCE_SAMPLES = 1024
"""Pending samples that trigger a write even before the flush interval is up."""


DISK_CHECK_INTERVAL_S = 2.0
"""How often (host seconds) the free space is checked while recording."""



class RunWriter:
    """Writer of one run file; see the module docstring for the threading and flushing contract."""

    def __init__(
        self,
        path: str | Path,
        description: layout.RunDescription,
        daq: layout.DaqLayout | None = None,
        camera: layout.CameraLayout | None = None,
        *,
        start_time: str | None = None,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
        expected_duration_s: float = 0.0,
        min_free_bytes: int = DEFAULT_MIN_FREE_BYTES,
        overwrite: bool = False,
    ) -> None:
        if not 0.0 < flush_interval_s <= MAX_FLUSH_INTERVAL_S:
            raise ValueError(
                f"flush_interval_s must be in (0, {MAX_FLUSH_INTERVAL_S}] s, got {flush_interval_s}"
            )
        self.path = Path(path)
        self.daq = daq if daq is not None else layout.DaqLayout()
        self.camera = camera
        _check_layout(self.daq, camera)
        json_texts = {
            "parameters": _to_json(description.parameters, "protocol parameters"),
            "calibration": _to_json(description.calibration, "calibration"),
            "metadata": _to_json(_string_pairs(description.metadata), "metadata", ordered=True),
        }
        check_output_path(
            self.path,
            required_bytes=estimate_run_bytes(expected_duration_s, self.daq, camera),
            min_free_bytes=min_free_bytes,
            overwrite=overwrite,
        )
        self.flush_interval_s = float(flush_interval_s)
        self.start_time = start_time if start_time is not None else layout.now_iso()
        try:
            self._file = h5py.File(self.path, "w" if overwrite else "x", libver=layout.LIBVER)
        except OSError as exc:
            raise StorageError(f"cannot create the run file: {exc}", path=self.path) from exc
        try:
            _create_layout(
                self._file, description, self.daq, camera, self.start_time, json_texts
            )
            self._file.swmr_mode = True
            self._file.flush()
        except BaseException:
            self._file.close()
            self.path.unlink(missing_ok=True)
            raise
        d = self._file[layout.DAQ]
        self._time = d["time"]
        self._channels = {name: d[name] for name in self.daq.channels}
        b = self._file[layout.DAQ_BLOCKS]
        self._blocks = {key: b[key] for key in ("first_sample", "counter", "host_time", "dropped")}
        self._rows_valid: h5py.Dataset = self._file[layout.ROWS_VALID]
        self._marked_valid = (0, 0)
        self._n_samples = 0
        self._n_blocks = 0
        self._last_t_s = -np.inf
        self._pending: list[dict[str, FloatArray]] = []
        self._pending_meta: list[tuple[int, int, float, int]] = []
        self._pending_samples = 0
        self._n_frames = 0
        self._last_frame_t_s = -np.inf
        self._n_events = 0
        self._last_flush = time.monotonic()
        self._min_free_bytes = int(min_free_bytes)
        self._last_disk_check = time.monotonic()
        self._owner: int | None = None
        self._closed = False
        self.status: layout.RunStatus = layout.RunStatus.RUNNING

    # -- appending ---------------------------------------------------------------------------------

    def append_daq(
        self,
        block: Mapping[str, ArrayLike],
        *,
        counter: int | None = None,
        host_time_s: float | None = None,
        dropped: int = 0,
    ) -> None:
        """Append a block of samples: ``t_s`` plus every channel of the layout, equal lengths.

        ``t_s`` is the time since the run start [s], finite and strictly increasing across blocks.
        Channel values are stored as given (a NaN from an over-range probe is recorded, not
        refused). ``counter`` is the device sample counter of the block's first sample (unwrapped),
        ``host_time_s`` the host monotonic clock when the block arrived, ``dropped`` the samples the
        device counter says were lost just before this block.
        """
        self._check_open_and_thread()
        columns = _block_columns(block, self.daq.channels, self._last_t_s)
        n = columns["t_s"].shape[0]
        if dropped < 0:
            raise DataError(f"dropped sample count must be >= 0, got {dropped}")
        if n:
            self._last_t_s = float(columns["t_s"][-1])
        first = self._n_samples + self._pending_samples
        meta = (
            first,
            -1 if counter is None else int(counter),
            float("nan") if host_time_s is None else float(host_time_s),
            int(dropped),
        )
        self._pending.append(columns)
        self._pending_meta.append(meta)
        self._pending_samples += n
        if self._pending_samples >= _COALESCE_SAMPLES:
            self._write_pending()
        self.maybe_flush()

    def append_frames(self, frames: ArrayLike, t_s: ArrayLike, seq: ArrayLike) -> None:
        """Append camera frames ``(k, H, W)`` uint8 with their times [s] and sequence numbers."""
        self._check_open_and_thread()
        if self.camera is None:
            raise StorageError("this run file was created without a camera stream", path=self.path)
        images = np.asarray(frames)
        if images.ndim == 2:
            images = images[np.newaxis]
        expected = (self.camera.height_px, self.camera.width_px)
        if images.dtype != np.uint8 or images.ndim != 3 or images.shape[1:] != expected:
            raise DataError(
                f"frames must be uint8 of shape (k, {expected[0]}, {expected[1]}), "
                f"got {images.dtype} {images.shape}",
                path=self.path,
            )
        times = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        seqs = np.atleast_1d(np.asarray(seq, dtype=np.int64))
        k = images.shape[0]
        if times.shape != (k,) or seqs.shape != (k,):
            raise DataError(f"{k} frames need {k} times and sequence numbers", path=self.path)
        _check_times(times, self._last_frame_t_s, "camera time")
        if k == 0:
            return
        cam = self._file[layout.CAMERA]
        self._extend(cam["frames"], images)
        self._extend(cam["time"], times)
        self._extend(cam["seq"], seqs)
        self._n_frames += k
        self._last_frame_t_s = float(times[-1])
        self.maybe_flush()

    def add_event(self, t_s: float, name: str, message: str = "") -> None:
        """Record a protocol step marker (written at once: events are rare and matter)."""
        self._check_open_and_thread()
        if not np.isfinite(t_s):
            raise DataError(f"event time must be finite, got {t_s!r}", path=self.path)
        ev = self._file[layout.EVENTS]
        self._extend(ev["time"], np.array([t_s], dtype=np.float64))
        self._extend(ev["name"], _fixed_text(name, layout.EVENT_NAME_BYTES))
        self._extend(ev["message"], _fixed_text(message, layout.EVENT_MESSAGE_BYTES))
        self._n_events += 1
        self.maybe_flush()

    # -- flushing and closing ---------------------------------------------------------------------

    def maybe_flush(self) -> bool:
        """Flush if ``flush_interval_s`` has passed since the last flush; True if it flushed."""
        now = time.monotonic()
        if self._min_free_bytes > 0 and now - self._last_disk_check >= DISK_CHECK_INTERVAL_S:
            self._last_disk_check = now
            self.check_free_space()
        if now - self._last_flush >= self.flush_interval_s:
            self.flush()
            return True
        return False

    def check_free_space(self) -> None:
        """Raise :class:`StorageError` when less than half of ``min_free_bytes`` is left.

        Stopping there, rather than at the first failed write, leaves room to close the file with
        its status and everything recorded so far.
        """
        folder = self.path.parent if str(self.path.parent) else Path(".")
        free = shutil.disk_usage(folder).free
        if free < self._min_free_bytes // 2:
            raise StorageError(
                f"disk nearly full: {free / 2**20:.1f} MiB free (reserve "
                f"{self._min_free_bytes / 2**20:.0f} MiB); recording stopped to keep the file intact",
                path=self.path,
            )

    def flush(self) -> None:
        """Write pending samples and make everything written so far visible to readers on disk;
        then (a second, small flush) record them as valid in ``daq/rows_valid``."""
        if self._closed:
            return
        self._write_pending()
        self._flush_file()
        self._mark_valid()
        self._last_flush = time.monotonic()

    def _flush_file(self) -> None:
        try:
            self._file.flush()
        except (OSError, RuntimeError) as exc:  # h5py raises either for a failed write
            raise StorageError(f"flush failed: {one_line(exc)}", path=self.path) from exc

    def _mark_valid(self) -> None:
        """Record the rows written so far as valid: call only after a flush that succeeded, so that
        ``rows_valid`` never counts rows that did not reach the disk (a full disk fails the flush
        and leaves the dataset lengths ahead of the data; readers read no further than this)."""
        rows = (self._n_samples, self._n_blocks)
        if rows == self._marked_valid:
            return
        try:
            self._rows_valid[:] = np.array(rows, dtype=np.int64)
        except (OSError, RuntimeError) as exc:
            raise StorageError(f"write failed: {one_line(exc)}", path=self.path) from exc
        self._flush_file()
        self._marked_valid = rows

    def close(
        self, status: layout.RunStatus = layout.RunStatus.COMPLETED, error: str | None = None
    ) -> None:
        """Write what is pending, record the final ``status`` (and ``error`` text), close the file.

        Idempotent: later calls do nothing.
        """
        if self._closed:
            return
        if status not in layout.FINAL_STATUSES:
            raise ValueError(
                f"status must be one of {', '.join(layout.FINAL_STATUSES)}, got {status!r}"
            )
        try:
            self._write_pending()
            self._flush_file()
            self._mark_valid()
        finally:
            try:
                entry = self._file[layout.ENTRY]
                entry["end_time"][()] = layout.fit_utf8(layout.now_iso(), layout.END_TIME_BYTES)
                entry["status"][()] = layout.fit_utf8(status, layout.STATUS_BYTES)
                entry["error"][()] = layout.fit_utf8(error or "", layout.ERROR_BYTES)
                self._file.flush()
                self.status = layout.RunStatus(status)
                self._mark_valid()  # rows whose first flush failed but this one wrote
            finally:
                self._closed = True
                try:
                    self._file.close()
                except (OSError, RuntimeError) as exc:
                    keep_alive(self._file)  # freeing it later can crash the HDF5 library
                    raise StorageError(f"close failed: {one_line(exc)}", path=self.path) from exc
                except BaseException:
                    keep_alive(self._file)
                    raise

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc is None:
            self.close(layout.RunStatus.COMPLETED)
        elif isinstance(exc, KeyboardInterrupt):
            self.close(layout.RunStatus.ABORTED, "interrupted (KeyboardInterrupt)")
        else:
            self.close(layout.RunStatus.FAILED, f"{type(exc).__name__}: {exc}")

    # -- state -------------------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def n_samples(self) -> int:
        """Samples accepted so far (written or pending)."""
        return self._n_samples + self._pending_samples

    @property
    def n_frames(self) -> int:
        return self._n_frames

    @property
    def n_events(self) -> int:
        return self._n_events

    # -- internals ---------------------------------------------------------------------------------

    def _check_open_and_thread(self) -> None:
        if self._closed:
            raise StorageError("the run file is closed", path=self.path)
        me = threading.get_ident()
        if self._owner is None:
            self._owner = me
        elif self._owner != me:
            raise RuntimeError(
                "RunWriter is single-threaded: feed it from one writer thread (queues in front)"
            )

    def _write_pending(self) -> None:
        """Write the coalesced blocks at their indices; on failure they stay pending (retryable)."""
        if not self._pending_meta:
            return
        blocks, metas = self._pending, self._pending_meta
        n_new = sum(col["t_s"].shape[0] for col in blocks)
        try:
            if n_new:
                start = self._n_samples
                _write_at(self._time, start, np.concatenate([col["t_s"] for col in blocks]))
                for name, dataset in self._channels.items():
                    _write_at(dataset, start, np.concatenate([col[name] for col in blocks]))
            meta = np.array(metas, dtype=object)
            for j, key in enumerate(("first_sample", "counter", "host_time", "dropped")):
                dtype = np.float64 if key == "host_time" else np.int64
                _write_at(self._blocks[key], self._n_blocks, meta[:, j].astype(dtype))
        except (OSError, RuntimeError) as exc:
            raise StorageError(f"write failed: {one_line(exc)}", path=self.path) from exc
        self._pending, self._pending_meta, self._pending_samples = [], [], 0
        self._n_samples += n_new
        self._n_blocks += len(metas)

    @staticmethod
    def _extend(dataset: h5py.Dataset, values: np.ndarray) -> None:
        start = dataset.shape[0]
        dataset.resize(start + values.shape[0], axis=0)
        dataset[start:] = values


def _write_at(dataset: h5py.Dataset, start: int, values: np.ndarray) -> None:
    """Write ``values`` at ``start`` (growing the dataset as needed): repeating it is harmless."""
    end = start + values.shape[0]
    if dataset.shape[0] < end:
        dataset.resize(end, axis=0)
    dataset[start:end] = values


def _fixed_text(text: str, n_bytes: int) -> np.ndarray:
    """One-element array of ``text`` in a fixed-length UTF-8 field of ``n_bytes``."""
    return np.array([layout.fit_utf8(text, n_bytes)], dtype=layout.fixed_utf8(n_bytes))


def _check_layout(daq: layout.DaqLayout, camera: layout.CameraLayout | None) -> None:
    if not daq.channels:
        raise ValueError("a run needs at least one DAQ channel")
    if len(set(daq.channels)) != len(daq.channels):
        raise ValueError(f"duplicate DAQ channel names in {daq.channels}")
    for name in daq.channels:
        if not name or "/" in name or name in ("time", "value", "blocks", "t_s"):
            raise ValueError(f"{name!r} cannot be a DAQ channel name")
    if not (np.isfinite(daq.sample_rate_hz) and daq.sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be positive, got {daq.sample_rate_hz}")
    if camera is not None and (camera.height_px <= 0 or camera.width_px <= 0):
        raise ValueError(f"camera frame size must be positive, got {camera}")
    if camera is not None:
        layout.frame_filters(camera.compression)  # ValueError naming an unknown compression


def _block_columns(
    block: Mapping[str, ArrayLike], channels: tuple[str, ...], last_t_s: float
) -> dict[str, FloatArray]:
    expected = {"t_s", *channels}
    missing = sorted(expected - set(block))
    unknown = sorted(set(block) - expected)
    if missing or unknown:
        raise DataError(f"DAQ block: missing {missing}, unknown {unknown}")
    columns = {name: np.ascontiguousarray(block[name], dtype=np.float64) for name in expected}
    n = columns["t_s"].shape
    for name, values in columns.items():
        if values.ndim != 1 or values.shape != n:
            raise DataError(f"DAQ block: '{name}' has shape {values.shape}, 't_s' has {n}")
    _check_times(columns["t_s"], last_t_s, "t_s")
    return columns


def _check_times(times: FloatArray, last: float, what: str) -> None:
    if not np.all(np.isfinite(times)):
        raise DataError(f"{what} must be finite", column=what)
    if times.size and (times[0] <= last or np.any(np.diff(times) <= 0)):
        raise DataError(f"{what} must increase strictly (after {last!r} s)", column=what)


def _string_pairs(metadata: Mapping[str, str]) -> dict[str, str]:
    for key, value in metadata.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise ValueError(f"metadata must map str to str, got {key!r}: {value!r}")
    return dict(metadata)


def _to_json(value: Mapping[str, Any], what: str, *, ordered: bool = False) -> str:
    """JSON text of ``value`` (keys sorted unless ``ordered``); NaN and non-JSON types refused."""
    try:
        return json.dumps(dict(value), allow_nan=False, sort_keys=not ordered)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} cannot be stored as JSON: {exc}") from exc


def _create_layout(
    f: h5py.File,
    description: layout.RunDescription,
    daq: layout.DaqLayout,
    camera: layout.CameraLayout | None,
    start_time: str,
    json_texts: dict[str, str],
) -> None:
    """Create every object of the layout (docs/run-file.md); nothing is created after this."""
    versions = layout.software_versions()
    f.attrs.update(
        {
            "default": "entry",
            "creator": f"rigctl {versions['rigctl']}",
            "file_time": start_time,
            "HDF5_Version": versions["hdf5"],
            "h5py_version": versions["h5py"],
        }
    )
    entry = f.create_group(layout.ENTRY)
    entry.attrs.update({"NX_class": "NXentry", "default": "plot"})
    entry.create_dataset("definition", data=layout.FORMAT_NAME).attrs["version"] = (
        layout.FORMAT_VERSION
    )
    entry.create_dataset("start_time", data=start_time)
    entry.create_dataset("end_time", data=b"", dtype=layout.fixed_utf8(layout.END_TIME_BYTES))
    entry.create_dataset(
        "status", data=layout.RunStatus.RUNNING.encode(), dtype=layout.fixed_utf8(layout.STATUS_BYTES)
    )
    entry.create_dataset("error", data=b"", dtype=layout.fixed_utf8(layout.ERROR_BYTES))
    entry.create_dataset("operator", data=description.operator)
    entry.create_dataset("notes", data=description.notes)
    entry.create_dataset("program_name", data="rigctl").attrs["version"] = versions["rigctl"]
    software = entry.create_group("software")
    software.attrs["NX_class"] = "NXcollection"
    for key, value in versions.items():
        software.create_dataset(key, data=value)
    protocol = entry.create_group("protocol")
    protocol.attrs["NX_class"] = "NXcollection"
    protocol.create_dataset("name", data=description.protocol)
    protocol.create_dataset("parameters", data=json_texts["parameters"]).attrs["content_type"] = (
        "application/json"
    )
    config = entry.create_group("config")
    config.attrs["NX_class"] = "NXnote"
    config.create_dataset("type", data="application/toml")
    config.create_dataset("data", data=description.config_toml)
    entry.create_dataset("calibration", data=json_texts["calibration"]).attrs["content_type"] = (
        "application/json"
    )
    entry.create_dataset("metadata", data=json_texts["metadata"]).attrs["content_type"] = (
        "application/json"
    )
    _create_daq(f, daq, start_time)
    if camera is not None:
        _create_camera(f, camera, start_time)
    _create_events(f)
    _create_plot(f, daq)


def _growing(group: h5py.Group, name: str, dtype: Any, chunk: int, unit: str = "") -> h5py.Dataset:
    ds = group.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(chunk,), dtype=dtype,
                              fletcher32=True)
    if unit:
        ds.attrs["units"] = unit
    return ds


def _create_daq(f: h5py.File, daq: layout.DaqLayout, start_time: str) -> None:
    group = f.create_group(layout.DAQ, track_order=True)
    group.attrs.update(
        {
            "NX_class": "NXlog",
            "sample_rate_hz": float(daq.sample_rate_hz),
            "channels": np.array(daq.channels, dtype=h5py.string_dtype()),
        }
    )
    time_ds = _growing(group, "time", np.float64, layout.DAQ_CHUNK_SAMPLES, "s")
    time_ds.attrs["start"] = start_time
    for name in daq.channels:
        _growing(group, name, np.float64, layout.DAQ_CHUNK_SAMPLES, daq.unit(name))
    group["value"] = group["ft_N" if "ft_N" in daq.channels else daq.channels[0]]
    blocks = f.create_group(layout.DAQ_BLOCKS)
    blocks.attrs["NX_class"] = "NXcollection"
    _growing(blocks, "first_sample", np.int64, layout.BLOCK_CHUNK)
    _growing(blocks, "counter", np.int64, layout.BLOCK_CHUNK, "counts")
    _growing(blocks, "host_time", np.float64, layout.BLOCK_CHUNK, "s")
    _growing(blocks, "dropped", np.int64, layout.BLOCK_CHUNK)
    valid = f.create_dataset(layout.ROWS_VALID, data=np.zeros(2, dtype=np.int64))
    valid.attrs["description"] = ("DAQ samples and block-table rows known to be on disk (written, "
                                  "then flushed); a reader reads no further")


def _create_camera(f: h5py.File, camera: layout.CameraLayout, start_time: str) -> None:
    group = f.create_group(layout.CAMERA)
    group.attrs.update({"NX_class": "NXcollection", "frame_rate_hz": float(camera.frame_rate_hz)})
    shape = (camera.height_px, camera.width_px)
    group.create_dataset(
        "frames",
        shape=(0, *shape),
        maxshape=(None, *shape),
        chunks=(1, *shape),
        dtype=np.uint8,
        fletcher32=True,
        **layout.frame_filters(camera.compression),
    )
    _growing(group, "time", np.float64, 256, "s").attrs["start"] = start_time
    _growing(group, "seq", np.int64, 256)


def _create_events(f: h5py.File) -> None:
    group = f.create_group(layout.EVENTS)
    group.attrs["NX_class"] = "NXcollection"
    _growing(group, "time", np.float64, layout.EVENT_CHUNK, "s")
    _growing(group, "name", layout.fixed_utf8(layout.EVENT_NAME_BYTES), layout.EVENT_CHUNK)
    _growing(group, "message", layout.fixed_utf8(layout.EVENT_MESSAGE_BYTES), layout.EVENT_CHUNK)


def _create_plot(f: h5py.File, daq: layout.DaqLayout) -> None:
    signal = "ft_N" if "ft_N" in daq.channels else daq.channels[0]
    plot = f.create_group(layout.PLOT)
    plot.attrs.update({"NX_class": "NXdata", "signal": signal, "axes": ["time"]})
    plot[signal] = f[layout.DAQ][signal]
    plot["time"] = f[layout.DAQ]["time"]
