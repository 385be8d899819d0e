"""One policy for every file or folder a command writes (docs/reliability.md, "Output files").

Checked before any work, so that a refusal never comes after a fit or a run:

1. The parent folder must exist and be writable (no command creates a tree of folders from a
   typo: ``/nonexistent/dir/runs`` is refused, not made).
2. An existing file is refused unless the user said ``--force``, and ``--force`` replaces only a
   regular file: a device (``/dev/null``), a pipe, a socket or a link to one is refused whatever
   ``--force`` says (replacing it would delete the device node).
3. A file another process holds open for writing (a ``rigctl run`` recording it) is never
   replaced, whatever ``--force`` says.
4. A report folder may exist (its files are replaced) but must be a folder.

Writers then write to a temporary name and rename on success (:mod:`rigctl.io.atomic`, and the
HDF5 writer's own temporary file), so a failed command leaves the old file intact.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import psutil

from rigctl.errors import UsageError

WRITE_MODES = ("w", "a", "r+", "a+", "w+")
"""File modes psutil reports for a file open for writing."""


def writer_of(path: Path) -> str | None:
    """The process (``"PID NAME"``) that holds ``path`` open for writing, if any (not this one).

    Linux and macOS list each process's open files; processes we may not inspect are skipped (a
    file of the user's own run is always visible to the user)."""
    try:
        target = path.resolve()
    except OSError:
        return None
    me = os.getpid()
    for proc in psutil.process_iter(["pid", "name"]):
        if proc.info["pid"] == me:
            continue
        try:
            files = proc.open_files()
        except (psutil.AccessDenied, psutil.NoSuchProcess, psutil.ZombieProcess, OSError):
            continue
        for f in files:
            if getattr(f, "mode", "r") in WRITE_MODES and Path(f.path) == target:
                return f"{proc.info['pid']} {proc.info['name']}"
    return None


_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"))


def not_a_regular_file(path: Path) -> str | None:
    """What ``path`` is when it exists and is not a regular file or a folder (``"a character
    device"``, ...; a symbolic link is judged by its target), else None."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def check_output_file(path: Path, option: str, *, force: bool = False) -> None:
    """Refuse (UsageError naming ``option``) an output file the policy does not allow."""
    _check_parent(path, option)
    if path.is_dir():
        raise UsageError(f"{option} {path} is a folder, not a file")
    kind = not_a_regular_file(path)
    if kind is not None:
        raise UsageError(f"{option} {path} is {kind}, not a regular file; it is never replaced, "
                         "whatever --force says (choose a file name)")
    if not path.exists():
        return
    holder = writer_of(path)
    if holder is not None:
        raise UsageError(f"{option} {path} is being written by process {holder}; it is never "
                         "replaced (choose another name)")
    if not force:
        raise UsageError(f"{option} {path} already exists; use --force to replace it")


def check_output_folder(path: Path, option: str) -> None:
    """Refuse a report folder that cannot be written (it may exist: its files are replaced)."""
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {path} exists and is not a folder")
    if path.exists():
        if not os.access(path, os.W_OK | os.X_OK):
            raise UsageError(f"{option} {path}: the folder is not writable")
        return
    _check_parent(path, option)


def _check_parent(path: Path, option: str) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise UsageError(f"{option} {path}: {parent} is not a folder (a file has its name)")
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: the folder {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: the folder {parent} is not writable")
