"""The Runs tab's analysis report, run in a worker process (:mod:`rigctl.gui.process_job`).

:func:`analyse_job` does what ``rigctl analyse RUN --out DIR`` does
(:func:`rigctl.analysis.pipeline.analyse_campaign`, then :func:`rigctl.analysis.report.write_report`)
and reports the analysis's progress bars to the window instead of a terminal. No Qt here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from rigctl.records.progress import Bar, Progress

if TYPE_CHECKING:  # the worker process does not import Qt
    from rigctl.gui.process_job import Report


@dataclass(frozen=True)
class AnalysisDone:
    """Where the report went, the figures it made, and what the analysis said."""

    index: str
    json_path: str
    figures: tuple[str, ...]
    lines: tuple[str, ...]


def default_report_folder(run_path: str | Path) -> Path:
    """``analysis_<run name>`` next to the run (as ``rigctl analyse`` without ``--out``)."""
    p = Path(run_path)
    return p.parent / f"analysis_{p.stem}"


class _ReportBar(Bar):
    """A progress bar that tells the window (``desc i/total``) instead of drawing on a terminal."""

    def __init__(self, report: Report, total: int, desc: str, unit: str) -> None:
        super().__init__(total, desc, unit, enabled=False)
        self._report, self._total, self._desc, self._unit, self._n = report, total, desc, unit, 0
        self._say()

    def _say(self) -> None:
        frac = self._n / self._total if self._total > 0 else math.nan
        self._report(f"{self._desc}: {self._n}/{self._total} {self._unit}", frac)

    def update(self, n: int = 1) -> None:
        self._n += n
        self._say()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class ReportProgress(Progress):
    """:class:`~rigctl.records.progress.Progress` whose bars go to a :data:`Report`."""

    def __init__(self, report: Report) -> None:
        super().__init__(False)
        self._report = report

    def bar(self, total: int, desc: str, unit: str = "it") -> Bar:
        return _ReportBar(self._report, total, desc, unit)


def analyse_job(report: Report, run_path: str, out_dir: str) -> AnalysisDone:
    """Analyse one run and write its report (the worker process's target)."""
    from rigctl.analysis.pipeline import analyse_campaign
    from rigctl.analysis.report import write_report
    from rigctl.io.outputs import check_output_folder

    out = Path(out_dir)
    check_output_folder(out, "report folder")
    progress = ReportProgress(report)
    report(f"analysing {Path(run_path).name}", math.nan)
    result = analyse_campaign([run_path], progress=progress)
    index, js = write_report(result, out, progress)
    lines = [f"{ra.name}: {len(ra.mechanics.passes)} pass(es), "
             f"{sum(p.cycles.n for p in ra.mechanics.passes)} cycles, {len(ra.notes)} note(s)"
             for ra in result.runs]
    lines += [f"note: {n}" for ra in result.runs for n in ra.notes]
    lines += [f"note: {n}" for n in result.notes]
    figures = tuple(sorted(str(p) for p in Path(index).parent.glob("*.png")))
    return AnalysisDone(str(index), str(js), figures, tuple(lines))
