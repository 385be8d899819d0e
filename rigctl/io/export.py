"""A run file's samples as an exchange-format CSV (import-format.md), with the run's provenance.

Used by ``rigctl export`` and the GUI's Runs tab. The CSV's ``# key: value`` lines are the run's own
metadata plus ``run.protocol``, ``run.status``, ``run.error``, ``run.start_time``, ``run.end_time``
and ``run.software`` (a key the run's metadata already has is kept as it is), so that an import
keeps a run that did not complete marked as such.
"""

from __future__ import annotations

from pathlib import Path

from rigctl.data import MeasuredRun
from rigctl.io.csv_format import write_csv
from rigctl.storage import RunReader


def export_csv(run_path: str | Path, csv_path: str | Path) -> MeasuredRun:
    """Write ``run_path``'s samples to ``csv_path``; returns the run written (for its sizes).

    The output policy (existing file, folder) is the caller's: see :mod:`rigctl.io.outputs`."""
    with RunReader(run_path) as reader:
        run = reader.to_measured()
        s = reader.summary()
        provenance = {"run.protocol": s.protocol, "run.status": s.status, "run.error": s.error,
                      "run.start_time": s.start_time, "run.end_time": s.end_time,
                      "run.software": ", ".join(f"{k} {v}" for k, v in reader.software.items())}
    for key, value in provenance.items():  # a key the run's own metadata has is kept as it is
        if value and key not in run.metadata:
            run.metadata[key] = " ".join(str(value).split())
    write_csv(csv_path, run)
    return run
