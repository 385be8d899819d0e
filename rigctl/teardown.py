"""Objects that must outlive the interpreter's teardown, and whether a normal exit is safe.

A run file whose close failed (a full disk, an I/O error) leaves the HDF5 library holding a
half-closed file, and freeing it can crash the interpreter at exit (h5py issue 914). The writer
hands such objects to :func:`keep_alive`; the command line asks :func:`unsafe_to_free` before it
exits and then leaves without the library's teardown. This module is light (no h5py): the command
line imports it whether or not a run file was written.
"""

from __future__ import annotations

_KEPT: list[object] = []


def keep_alive(obj: object) -> None:
    """Never free ``obj`` (kept referenced until the process ends)."""
    _KEPT.append(obj)


def unsafe_to_free() -> bool:
    """True if some object was kept alive because freeing it could crash the process."""
    return bool(_KEPT)
