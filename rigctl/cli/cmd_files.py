"""Run-file commands: ``rigctl export``, ``rigctl import``, ``rigctl info``.

* ``export RUN.h5 --csv out.csv``: the run's samples as an exchange-format CSV (import-format.md).
* ``import file.csv --out RUN.h5``: a CSV run as an HDF5 run file (docs/run-file.md).
* ``info RUN.h5`` (or a ``.csv``): protocol, times, status, duration, samples, channels and units,
  drops, events, frames.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from rigctl.errors import UsageError
from rigctl.io.json_values import jsonable
from rigctl.io.outputs import check_output_file
from rigctl.status import RunStatus

# numpy, h5py and the storage layer are imported inside the commands: `rigctl --help` and the other
# commands do not pay for them.


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    export = subparsers.add_parser(
        "export", help="write a run file's samples as CSV", description="Export a run to CSV."
    )
    export.add_argument("run", type=Path, metavar="RUN.h5", help="HDF5 run file")
    export.add_argument("--csv", type=Path, required=True, metavar="OUT.csv", help="CSV to write")
    export.add_argument("--force", action="store_true",
                        help="replace an existing CSV (never a file being written)")
    export.set_defaults(func=run_export)

    imp = subparsers.add_parser(
        "import", help="make a run file from a CSV run", description="Import a CSV run."
    )
    imp.add_argument("csv", type=Path, metavar="FILE.csv", help="exchange-format CSV")
    imp.add_argument("--out", type=Path, required=True, metavar="RUN.h5", help="run file to make")
    imp.add_argument("--operator", default="", help="operator (default: the CSV's, if any)")
    imp.add_argument("--notes", default="", help="free-text notes stored with the run")
    imp.add_argument("--force", action="store_true", help="replace an existing run file")
    imp.set_defaults(func=run_import)

    info = subparsers.add_parser(
        "info", help="describe a run file or CSV", description="Describe a run (.h5 or .csv)."
    )
    info.add_argument("path", type=Path, metavar="RUN", help="HDF5 run file or CSV")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(func=run_info)


def run_export(args: argparse.Namespace) -> int:
    from rigctl.io.export import export_csv
    from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES

    _require_suffix(args.run, RUN_FILE_SUFFIXES, "RUN")
    _require_suffix(args.csv, CSV_SUFFIXES, "--csv")
    check_output_file(args.csv, "--csv", force=args.force)
    run = export_csv(args.run, args.csv)
    print(f"wrote {args.csv} ({run.n_samples} samples, {len(run.columns())} columns)")
    return 0


def run_import(args: argparse.Namespace) -> int:
    from rigctl.io.csv_format import read_csv
    from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES
    from rigctl.io.plausibility import checked
    from rigctl.storage import write_measured_run

    _require_suffix(args.csv, CSV_SUFFIXES, "FILE")
    _require_suffix(args.out, RUN_FILE_SUFFIXES, "--out")
    check_output_file(args.out, "--out", force=args.force)
    run = checked(read_csv(args.csv), str(args.csv))
    status, error = _imported_status(run.metadata)
    write_measured_run(
        args.out,
        run,
        protocol="import",
        parameters={"source": args.csv.name},
        operator=args.operator,
        notes=args.notes,
        overwrite=args.force,
        status=status,
        error=error,
    )
    if status != RunStatus.COMPLETED:
        print(f"note: the original run ended {run.metadata.get('run.status')}: imported as "
              f"{status} ({error})", file=sys.stderr)
    print(f"wrote {args.out} ({run.n_samples} samples from {args.csv})")
    return 0


def run_info(args: argparse.Namespace) -> int:
    from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES
    from rigctl.storage import RunReader

    path: Path = args.path
    if path.suffix.lower() in CSV_SUFFIXES:
        summary = _csv_summary(path)
    else:
        _require_suffix(path, RUN_FILE_SUFFIXES, "RUN")
        with RunReader(path) as reader:
            summary = reader.summary().__dict__
    if args.json:
        print(json.dumps(jsonable(summary), indent=2, default=str, allow_nan=False))
    else:
        sys.stdout.write(format_summary(summary))
    return 0


def _imported_status(metadata: dict[str, str]) -> tuple[RunStatus, str | None]:
    """The status an imported run keeps from the ``run.status``/``run.error`` an export wrote: a
    run that did not complete stays so (one never closed, status running, was killed or was still
    being written, and is imported as aborted)."""
    original = metadata.get("run.status", "").strip()
    error = metadata.get("run.error", "").strip()
    if original in ("", RunStatus.COMPLETED):
        return RunStatus.COMPLETED, None
    if original == RunStatus.RUNNING:
        return RunStatus.ABORTED, ("the original run was not closed when it was exported (killed, "
                                   "or still being written)")
    try:
        return RunStatus(original), error or f"the original run ended {original}"
    except ValueError:
        return RunStatus.ABORTED, f"the original run's status was {original!r}"


def format_summary(s: dict[str, Any]) -> str:
    """The summary as aligned ``label  value`` lines."""
    rate = s["sample_rate_hz"]
    channels = ", ".join(f"{name} [{unit or '-'}]" for name, unit in s["channels"].items())
    params = json.dumps(s["parameters"]) if s["parameters"] else ""
    rows = [
        ("file", s["path"]),
        ("protocol", f"{s['protocol']} {params}".strip()),
        ("status", _status_text(s["status"], s["error"])),
        ("start", s["start_time"] or "-"),
        ("end", s["end_time"] or "-"),
        ("duration", f"{s['duration_s']:.6g} s"),
        ("samples", f"{s['n_samples']} at {rate:.6g} Hz" if math.isfinite(rate) else "-"),
        ("channels", channels),
        ("dropped", f"{s['dropped_samples']} samples, {s['dropped_frames']} frames"),
        ("events", str(s["n_events"])),
        ("frames", str(s["n_frames"])),
        ("operator", s["operator"] or "-"),
    ]
    if s["notes"]:
        rows.append(("notes", s["notes"]))
    return "".join(f"{label:<10}{value}\n" for label, value in rows)


def _status_text(status: str, error: str) -> str:
    if status == RunStatus.RUNNING:
        return "running (still being written, or the writer stopped without closing the file)"
    return f"{status} ({error})" if error else status


def _csv_summary(path: Path) -> dict[str, Any]:
    from rigctl.io.csv_format import read_csv
    from rigctl.io.plausibility import checked
    from rigctl.storage import unit_of
    from rigctl.storage.text import printable

    run = checked(read_csv(path), str(path))
    meta = {printable(k): printable(v) for k, v in run.metadata.items()}
    return {
        "path": str(path),
        "protocol": meta.get("protocol", "csv"),
        "parameters": {},
        "status": "csv (no recording status)",
        "error": "",
        "start_time": meta.get("start_time", ""),
        "end_time": meta.get("end_time", ""),
        "operator": meta.get("operator", ""),
        "notes": meta.get("notes", ""),
        "n_samples": run.n_samples,
        "duration_s": run.duration_s,
        "sample_rate_hz": run.sample_rate_hz,
        "channels": {printable(name): unit_of(name) for name in run.columns() if name != "t_s"},
        "dropped_samples": 0,
        "n_events": 0,
        "n_frames": 0,
        "dropped_frames": 0,
        "metadata": meta,
    }


def _require_suffix(path: Path, suffixes: tuple[str, ...], what: str) -> None:
    if path.suffix.lower() not in suffixes:
        raise UsageError(f"{what} {path}: expected a {' or '.join(suffixes)} file")
