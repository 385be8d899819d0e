"""Checks made before a run starts: can the run file be created, and is there room for it?

Failing here, before any motion or acquisition, is the point: a run that cannot be stored must not
start. The estimate of the bytes a run needs is the raw sample size plus the frames at the size
measured for contact images with the run's compression
(:data:`rigctl.storage.layout.FRAME_BYTES_PER_PIXEL`); the margin ``min_free_bytes`` covers
metadata, chunk padding, noisier images and the rest of the system.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from rigctl.storage.errors import StorageError
from rigctl.storage.layout import FRAME_BYTES_PER_PIXEL, CameraLayout, DaqLayout

DEFAULT_MIN_FREE_BYTES = 64 * 1024 * 1024
"""Free space kept in reserve beyond a run's estimated size."""

_BYTES_PER_VALUE = 8  # float64 samples and times


def estimate_run_bytes(
    duration_s: float, daq: DaqLayout, camera: CameraLayout | None = None, *, at_most: bool = False
) -> int:
    """Bytes of ``duration_s`` of recording: samples (channels + time, float64) plus frames.

    Frames count at the size measured for contact images with ``camera.compression``, or
    uncompressed with ``at_most`` (images that do not compress: noise, a saturated sensor).
    """
    per_s = daq.sample_rate_hz * _BYTES_PER_VALUE * (len(daq.channels) + 1)
    if camera is not None:
        per_s += camera.frame_rate_hz * (frame_bytes(camera, at_most=at_most) + 2 * _BYTES_PER_VALUE)
    return int(per_s * max(duration_s, 0.0))


def frame_bytes(camera: CameraLayout, *, at_most: bool = False) -> float:
    """Stored bytes of one frame: measured for contact images, or the raw pixels ``at_most``."""
    pixels = camera.height_px * camera.width_px
    return float(pixels) if at_most else pixels * FRAME_BYTES_PER_PIXEL[camera.compression]


def check_output_path(
    path: str | Path,
    *,
    required_bytes: int = 0,
    min_free_bytes: int = DEFAULT_MIN_FREE_BYTES,
    overwrite: bool = False,
) -> Path:
    """Raise :class:`StorageError` unless ``path`` can be created with ``required_bytes`` to spare.

    Checks, in order: the parent folder exists and is a folder; the target is not a folder and does
    not exist (unless ``overwrite``), and is never open for writing by another process (a run being
    recorded, whatever ``overwrite`` says); the folder is writable by this process; the file system has
    ``required_bytes + min_free_bytes`` free. Returns the path.
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.exists():
        raise StorageError(f"the folder {str(folder)!r} does not exist", path=target)
    if not folder.is_dir():
        raise StorageError(f"{str(folder)!r} is not a folder", path=target)
    if target.is_dir():
        raise StorageError("is a folder, not a file name", path=target)
    from rigctl.io.outputs import not_a_regular_file

    kind = not_a_regular_file(target)
    if kind is not None:  # /dev/null: replacing it would delete the device node
        raise StorageError(f"is {kind}, not a regular file; it is never replaced", path=target)
    if target.exists() and not overwrite:
        raise StorageError("already exists (refusing to overwrite a run file)", path=target)
    if target.exists():
        from rigctl.io.outputs import writer_of

        holder = writer_of(target)
        if holder is not None:
            raise StorageError(f"is being written by process {holder}; it is never replaced "
                               "(choose another name)", path=target)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StorageError(f"the folder {str(folder)!r} is not writable", path=target)
    free = shutil.disk_usage(folder).free
    needed = int(required_bytes) + int(min_free_bytes)
    if free < needed:
        raise StorageError(
            f"not enough free space: {_mib(free)} free, the run needs {_mib(required_bytes)} "
            f"plus {_mib(min_free_bytes)} in reserve",
            path=target,
        )
    return target


def _mib(n_bytes: int | float) -> str:
    return f"{n_bytes / 2**20:.1f} MiB"
