"""Touch every piece of an HDF5 file's metadata once, so that a later read cannot hang on it.

A SWMR reader retries a metadata read whose checksum fails with doubling sleeps (the writer may be
changing it): on a damaged file (a copy cut short, flipped bytes) that is a wait of hours that
Ctrl-C cannot stop. A plain read-only open tries once and fails at once. :func:`walk_metadata`
reads every object header, attribute and chunk index, so that a file it passes has no damaged
metadata left to find; :mod:`rigctl.storage.safe_open` runs it in this process on a plain open,
and in a child process (this file run as a script, killed after a timeout) before a SWMR open.

Run as a script (``python probe.py FILE``), it prints ``ready`` once h5py is imported, then
``ok`` or ``error: <one line>`` after opening the file for SWMR and walking it. It imports only
h5py, so that the child starts as fast as it can.
"""

from __future__ import annotations

import sys
from typing import Any

import h5py

READY = "ready"
OK = "ok"


def walk_metadata(f: h5py.File) -> None:
    """Read every object, attribute and chunk index of ``f``; raises what h5py raises."""
    _touch(f)
    f.visititems(lambda _name, obj: _touch(obj))


def _touch(obj: Any) -> None:
    for key in obj.attrs:
        obj.attrs[key]
    if isinstance(obj, h5py.Dataset):
        obj.shape  # noqa: B018  (the dataspace message)
        if obj.chunks is not None:
            obj.id.get_num_chunks()  # walks the chunk index


def _main(path: str) -> int:
    print(READY, flush=True)
    try:
        with h5py.File(path, "r", swmr=True) as f:
            walk_metadata(f)
    except Exception as exc:  # any failure is the answer, printed on one line
        print("error: " + " ".join(str(exc).split()), flush=True)
        return 1
    print(OK, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1]))
