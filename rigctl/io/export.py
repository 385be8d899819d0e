"""A run file's samples as an exchange-format CSV (import-format.md), with the run's provenance.

Used by ``rigctl export`` and the GUI's Runs tab. The CSV's ``# key: value`` lines are the run's own
metadata plus ``run.protocol``, ``run.status``, ``run.error``, ``run.start_time``, ``run.end_time``
and ``run.software`` (a key the run's metadata already has is kept as it is), so that an import
keeps a run that did not complete marked as such.

A run whose probes were re-centred (``probe_recentre`` events) is exported with ``d1_m``/``d2_m``
stitched across the mount moves (:func:`rigctl.records.delta_stitch.stitch_run`, what every reader
of the run file reads), the columns as recorded kept beside them as ``d1_recorded_m``/
``d2_recorded_m`` and a ``delta.stitched`` metadata line (docs/csv-format.md, "Re-centred probes").
"""

from __future__ import annotations

from pathlib import Path

from rigctl.data import MeasuredRun
from rigctl.io.csv_format import write_csv
from rigctl.storage import RunEvent, RunReader

RECORDED_COLUMNS = {"d1_m": "d1_recorded_m", "d2_m": "d2_recorded_m"}
"""The extra column a re-centred probe's recorded readings are exported as."""


def _stitched(run: MeasuredRun, events: list[RunEvent]) -> MeasuredRun:
    """``run`` with its probe columns stitched and the recorded ones kept as extra columns."""
    # the one stitching of every reader of a run file (rigctl.records, imported here for the
    # export alone: the CSV carries the delta the analysis and the workbench read)
    from rigctl.records.delta_stitch import is_stitched, mount_moves, stitch_run

    if is_stitched(run):
        return run
    out = stitch_run(run, events)
    for column in mount_moves(events):
        out.extra.setdefault(RECORDED_COLUMNS[column], getattr(run, column))
    return out


def export_csv(run_path: str | Path, csv_path: str | Path) -> MeasuredRun:
    """Write ``run_path``'s samples to ``csv_path``; returns the run written (for its sizes).

    The output policy (existing file, folder) is the caller's: see :mod:`rigctl.io.outputs`."""
    with RunReader(run_path) as reader:
        run = reader.to_measured()
        events = reader.events()
        s = reader.summary()
        provenance = {"run.protocol": s.protocol, "run.status": s.status, "run.error": s.error,
                      "run.start_time": s.start_time, "run.end_time": s.end_time,
                      "run.software": ", ".join(f"{k} {v}" for k, v in reader.software.items())}
    run = _stitched(run, events)
    for key, value in provenance.items():  # a key the run's own metadata has is kept as it is
        if value and key not in run.metadata:
            run.metadata[key] = " ".join(str(value).split())
    write_csv(csv_path, run)
    return run
