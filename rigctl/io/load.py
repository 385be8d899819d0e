"""Turn what a user names on the command line (files, folders) into measured runs.

Each path is an exchange-format ``.csv`` file, an HDF5 run file (``.h5``, ``.hdf5``, ``.nxs``), or a folder:
a folder means every ``*.csv`` and ``*.h5`` file directly in it, in sorted name order, each one
run of a campaign (import-format.md). Missing paths, empty folders and unknown file types raise
:class:`rigctl.data.DataError` naming the path.

A ``rig_description.toml`` beside a run file (in the campaign folder) describes the rig of every
run there: its entries become the runs' ``rig.<key>`` metadata (docs/csv-format.md, "Rig
description"): a number as is, a two-number list ``[lo, hi]`` as the range ``lo..hi``, a boolean as
yes/no. A key that a file states itself must agree with it.
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from rigctl.data import DataError, MeasuredRun
from rigctl.io.csv_format import read_csv
from rigctl.io.plausibility import checked
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


RIG_FILE = "rig_description.toml"
"""Not ``rig.toml``: that name is usual for a rig configuration (docs/configuration.md)."""


def rig_metadata(folder: Path) -> dict[str, str]:
    """``rig.<key>`` metadata from ``folder/rig_description.toml`` ({} when there is none)."""
    path = folder / RIG_FILE
    if not path.is_file():
        return {}
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"not a valid TOML file: {exc}", path=path) from None
    out: dict[str, str] = {}
    for key, value in table.items():
        if isinstance(value, bool):
            text = "yes" if value else "no"
        elif isinstance(value, int | float):
            text = repr(float(value))
        elif (isinstance(value, list) and len(value) == 2
              and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
            text = f"{float(value[0])!r}..{float(value[1])!r}"
        else:
            raise DataError(f"key {key!r}: expected a number, [lo, hi] or true/false, "
                            f"got {value!r}", path=path)
        out[f"rig.{key}"] = text
    return out


def load_run(path: str | Path) -> MeasuredRun:
    """One run from a ``.csv`` or ``.h5`` file, with the rig description beside it merged in."""
    p = Path(path)
    run = checked(read_run(p) if p.suffix.lower() in RUN_FILE_SUFFIXES else read_csv(p), str(p))
    beside = rig_metadata(p.parent)
    if not beside:
        return run
    for key, text in beside.items():
        own = run.metadata.get(key)
        if own is not None and own.strip() != text:
            try:
                same = float(own) == float(text)
            except ValueError:
                same = False
            if not same:
                raise DataError(f"metadata {key!r} = {own!r} disagrees with {RIG_FILE} "
                                f"({text!r})", path=p)
    return replace(run, metadata={**beside, **run.metadata})


def load_runs(paths: Sequence[str | Path]) -> list[MeasuredRun]:
    """Every run the paths name (see the module docstring), in order."""
    return [load_run(p) for p in expand_paths(paths)]
