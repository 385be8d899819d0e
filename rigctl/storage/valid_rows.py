"""Which leading rows of a growing dataset are really in the file.

A dataset can say it has more rows than were ever written: a disk that filled while the writer
flushed leaves the new length recorded but the new chunks unwritten (they read as zeros), and a
copy cut short loses the chunks beyond the cut (they read as zeros too). The chunk index tells:
a row is there when its chunk is allocated and lies wholly within the file. The times tell the
rest: the writer only stores strictly increasing finite times, so the first time that is not is
where the written part ends.
"""

from __future__ import annotations

import h5py
import numpy as np

from rigctl.data import FloatArray


def rows_in_file(ds: h5py.Dataset, size_bytes: int) -> int:
    """The leading rows of ``ds`` whose chunks are allocated and end within ``size_bytes``."""
    n = int(ds.shape[0]) if ds.shape else 0
    if n == 0:
        return 0
    if ds.chunks is None:
        offset = ds.id.get_offset()
        inside = offset is not None and offset + ds.id.get_storage_size() <= size_bytes
        return n if inside else 0
    rows = int(ds.chunks[0])
    present: set[int] = set()

    def note(info: h5py.h5d.StoreInfo) -> None:
        if info.byte_offset is not None and info.byte_offset + info.size <= size_bytes:
            present.add(int(info.chunk_offset[0]) // rows)

    ds.id.chunk_iter(note)
    k = 0
    while k in present:
        k += 1
    return min(n, k * rows)


def increasing_prefix(t_s: FloatArray) -> int:
    """The length of the leading part of ``t_s`` that is finite and strictly increasing."""
    if t_s.size == 0:
        return 0
    bad = ~np.isfinite(t_s)
    bad[1:] |= np.diff(t_s) <= 0
    found = np.flatnonzero(bad)
    return int(found[0]) if found.size else int(t_s.size)
