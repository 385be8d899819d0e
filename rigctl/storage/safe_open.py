"""Open a run file so that no later read of it can hang, whatever damage it has.

HDF5 opened for SWMR retries a metadata read whose checksum fails, sleeping twice as long each
time, because a writer may be rewriting it: on a damaged file that is hours that Ctrl-C cannot
stop (a file cut at a third of its length, 16 bytes flipped in its metadata). A plain read-only open
tries once and fails at once. So:

1. the superblock's declared end of file is compared with the file's size (no HDF5 call);
2. a whole file (a closed run: the normal case) is opened plainly, its global heap collections
   (the variable-length strings: no checksum, and a damaged one makes the HDF5 library loop for
   ever in this process) checked by :func:`rigctl.storage.heap_check.check_global_heaps` without
   HDF5 reading them, and every piece of its metadata read once in this process
   (:func:`rigctl.storage.probe.walk_metadata`): tens of milliseconds together; damage is then a
   one-line :class:`DataError` at once;
3. a file that another process is writing (a live run) is opened for SWMR at once: HDF5's
   retries are then what they are for, a writer changing the metadata under the reader;
4. any other file a plain open refuses (its writer died: HDF5's "open for writing" flag is still
   set; or damaged) and a truncated file are first opened and walked the same way in a child
   process killed after :data:`OPEN_TIMEOUT_S` (waiting for it is interruptible); only if that
   succeeds is it opened for SWMR here, and its global heap checked as in 2. Its metadata then
   holds nothing a read could hang on.
"""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import h5py

from rigctl.data import DataError
from rigctl.storage import heap_check, probe
from rigctl.storage.text import one_line

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

OPEN_TIMEOUT_S = 5.0
"""How long the child process may take to open and walk a file once it has started: an intact
file takes milliseconds; one damaged in its metadata makes a SWMR open retry for hours."""
START_TIMEOUT_S = 60.0
"""How long the child may take to start (import h5py) on a loaded machine; not part of the
verdict on the file."""


@dataclass(frozen=True)
class OpenedFile:
    """A run file opened for reading, and what is known about its damage."""

    file: h5py.File
    size_bytes: int
    truncation: str | None
    """``truncated file: N bytes of the M its header declares`` when it is shorter, else None."""


def open_run_file(path: Path) -> OpenedFile:
    """Open ``path`` read-only (see the module docstring); :class:`DataError` in one line when it
    cannot be read at all."""
    head, size = _head(path)
    declared = declared_size(head)
    truncation = None
    if declared is not None and size < declared:
        truncation = f"truncated file: {size:,} bytes of the {declared:,} its header declares"
    else:
        try:
            f = h5py.File(path, "r")
        except OSError:
            if _being_written(path):
                return OpenedFile(_open_swmr(path), size, None)
            # its writer died, or damaged: the child decides
        else:
            try:
                _check_heaps(f, path, size)
                probe.walk_metadata(f)
            except DataError:
                f.close()
                raise
            except Exception as exc:  # any failure of the walk is damage
                f.close()
                raise DataError(f"damaged HDF5 metadata ({one_line(exc)}): nothing can be read",
                                path=path) from None
            return OpenedFile(f, size, None)
    problem = probe_in_child(path, OPEN_TIMEOUT_S)
    if problem is not None:
        if truncation:
            raise DataError(f"{truncation} ({problem}; a copy cut short or a damaged disk): "
                            "nothing can be read", path=path)
        raise DataError(f"damaged HDF5 file ({problem}): nothing can be read", path=path)
    f = _open_swmr(path)
    try:
        _check_heaps(f, path, size)  # the child read the attributes, not the string datasets
    except BaseException:
        f.close()
        raise
    return OpenedFile(f, size, truncation)


def _check_heaps(f: h5py.File, path: Path, size: int) -> None:
    """:func:`rigctl.storage.heap_check.check_global_heaps`, its verdict as a :class:`DataError`."""
    try:
        with open(path, "rb") as fh:
            heap_check.check_global_heaps(f, fh, size)
    except heap_check.HeapDamageError as exc:
        raise DataError(f"damaged HDF5 global heap ({exc}): nothing can be read",
                        path=path) from None
    except Exception as exc:  # HDF5 refusing an object on the way: damaged metadata
        raise DataError(f"damaged HDF5 metadata ({one_line(exc)}): nothing can be read",
                        path=path) from None


def _open_swmr(path: Path) -> h5py.File:
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError as exc:
        raise DataError(f"cannot open as HDF5: {one_line(exc)}", path=path) from None


def _being_written(path: Path) -> bool:
    """Whether another process holds ``path`` open for writing (a run being recorded)."""
    from rigctl.io.outputs import writer_of  # the process table: only asked here

    return writer_of(path) is not None


def _head(path: Path) -> tuple[bytes, int]:
    """The file's first 64 bytes and its size; refuses what is not HDF5 at all."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
        size = path.stat().st_size
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from None
    if head and not head.startswith(HDF5_SIGNATURE[: len(head)]):
        raise DataError("not an HDF5 file (no HDF5 signature at its start)", path=path)
    if len(head) < 16:
        raise DataError(f"truncated file: only {size:,} bytes, not even an HDF5 header", path=path)
    return head, size


def declared_size(head: bytes) -> int | None:
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


def probe_in_child(path: Path, timeout_s: float) -> str | None:
    """Open ``path`` for SWMR and walk its metadata in a child process; None if that worked within
    ``timeout_s`` of the child being ready, else what went wrong (one line). The child is killed
    on timeout and on Ctrl-C (the wait here is interruptible)."""
    proc = subprocess.Popen([sys.executable, probe.__file__, str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, text=True)
    lines: queue.Queue[str | None] = queue.Queue()

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put(line.strip())
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    try:
        first = _next_line(lines, START_TIMEOUT_S)
        if first != probe.READY:
            return "the checking process did not start"
        answer = _next_line(lines, timeout_s)
        if answer is None:
            return f"its metadata could not be read within {timeout_s:g} s"
        if answer == probe.OK:
            return None
        return answer.removeprefix("error: ")
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


def _next_line(lines: queue.Queue[str | None], timeout_s: float) -> str | None:
    try:
        return lines.get(timeout=timeout_s)
    except queue.Empty:
        return None
