"""Turn what a user names on the command line (files, folders) into measured runs.

Each path is an exchange-format ``.csv`` file, an HDF5 run file (``.h5``, ``.hdf5``, ``.nxs``), or a folder:
a folder means every ``*.csv`` and ``*.h5`` file directly in it, in sorted name order, each one
run of a campaign (import-format.md). Missing paths, empty folders and unknown file types raise
:class:`rigctl.data.DataError` naming the path.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rigctl.data import DataError, MeasuredRun
from rigctl.io.csv_format import read_csv
from rigctl.storage.reader import read_run

CSV_SUFFIXES = (".csv",)
RUN_FILE_SUFFIXES = (".h5", ".hdf5", ".nxs")
FOLDER_PATTERNS = ("*.csv", "*.h5")


def expand_paths(paths: Sequence[str | Path]) -> list[Path]:
    """The run files the paths name, folders expanded (sorted), in the order given."""
    if isinstance(paths, str | Path):
        raise TypeError("expand_paths takes a sequence of paths, not a single path")
    if not paths:
        raise DataError("no run files given")
    files: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            found = sorted({p for pattern in FOLDER_PATTERNS for p in path.glob(pattern)})
            found = [p for p in found if p.is_file() and not p.name.startswith(".")]
            if not found:
                raise DataError("folder has no *.csv or *.h5 run files", path=path)
            files.extend(found)
        elif path.is_file():
            if path.suffix.lower() not in CSV_SUFFIXES + RUN_FILE_SUFFIXES:
                raise DataError(
                    f"unknown file type {path.suffix!r}: expected .csv, .h5 or a folder", path=path
                )
            files.append(path)
        else:
            raise DataError("no such file or folder", path=path)
    return files


def load_run(path: str | Path) -> MeasuredRun:
    """One run from a ``.csv`` or ``.h5`` file."""
    p = Path(path)
    if p.suffix.lower() in RUN_FILE_SUFFIXES:
        return read_run(p)
    return read_csv(p)


def load_runs(paths: Sequence[str | Path]) -> list[MeasuredRun]:
    """Every run the paths name (see the module docstring), in order."""
    return [load_run(p) for p in expand_paths(paths)]
