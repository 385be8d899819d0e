"""The Runs tab: open a recorded run (HDF5, also one still being recorded, or an exchange-format CSV)
and see all of it: overview plots, events, status, parameters, configuration; export it to CSV, run it
again, analyse it.

* HDF5 runs are read with :class:`~rigctl.storage.reader.RunReader` (SWMR: a run being recorded can
  be opened and followed). The samples are read in pieces of at most ``READ_CHUNK`` per timer tick, so
  a long run fills the plots progressively and the window never waits on the disk; while the run's
  status is ``running`` the tab looks for new samples every ``FOLLOW_INTERVAL_MS``.
* The plots are an overview of the whole run: at most about ``OVERVIEW_POINTS`` samples, each bin's
  lowest and highest Ft kept (:class:`~rigctl.gui.decimate.PeakEnvelope`), Fn and delta taken at
  the same samples (so Ft against delta is made of real sample pairs).
* CSV runs are read whole with :func:`rigctl.io.load.load_run` (the loader of ``rigctl analyse`` and
  ``rigctl model``).
* Export CSV: :func:`rigctl.io.export.export_csv` (what ``rigctl export`` does), refusing what the
  output policy refuses (:func:`rigctl.io.outputs.check_output_file`: never a file being written).
* "Run again with these parameters" emits :attr:`RunsPanel.run_again` (protocol, parameters); the main
  window fills the Protocols tab with :func:`fill_run_panel`.
* Analysis report: ``rigctl analyse`` in a worker process (:mod:`rigctl.gui.analysis_job`), with
  progress and cancel; the report's path and figures are shown when done.

Errors go to the tab's log and to :attr:`RunsPanel.status_message` (the main window's status bar).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer, QUrl, Signal
from PySide6.QtGui import QDesktopServices, QFont, QPixmap
from PySide6.QtWidgets import (
    QFileDialog,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from rigctl.data import MeasuredRun
from rigctl.gui.analysis_job import AnalysisDone, analyse_job, default_report_folder
from rigctl.gui.decimate import PeakEnvelope
from rigctl.gui.process_job import ProcessJob
from rigctl.status import RunStatus

READ_CHUNK = 1 << 17
"""Samples read per timer tick (about 2 minutes at 1024 Hz)."""
FOLLOW_INTERVAL_MS = 2000
"""How often a run still being recorded is looked at for new samples."""
OVERVIEW_POINTS = 6000
MAX_READ_FAILURES = 3
"""Consecutive failed reads of a run being written before the tab stops following it."""
_BLUE, _RED, _GREEN, _ORANGE = "#1565c0", "#c62828", "#2e7d32", "#e65100"
_CHANNELS = ("t_s", "ft_N", "fn_N", "delta_m")


def _item(text: str, tip: str = "") -> QTableWidgetItem:
    item = QTableWidgetItem(text)
    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
    if tip:
        item.setToolTip(tip)
    return item


def _fill_table(table: QTableWidget, rows: list[tuple[str, ...]]) -> None:
    table.setRowCount(len(rows))
    for r, cells in enumerate(rows):
        for c, text in enumerate(cells):
            table.setItem(r, c, _item(text, text if len(text) > 40 else ""))


def _table(headers: tuple[str, ...]) -> QTableWidget:
    t = QTableWidget(0, len(headers))
    t.setHorizontalHeaderLabels(list(headers))
    t.verticalHeader().setVisible(False)
    t.horizontalHeader().setStretchLastSection(True)
    t.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
    return t


def parameter_text(value: Any) -> str:
    """A recorded parameter value as the Protocols tab takes it (lists comma-separated)."""
    if isinstance(value, list | tuple):
        return ", ".join(repr(float(v)) for v in value)
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def fill_run_panel(panel: Any, protocol: str, parameters: Mapping[str, Any]) -> str:
    """Set the Protocols tab (a :class:`~rigctl.gui.run_panel.RunPanel`) to ``protocol`` with
    ``parameters``; returns what was done. Raises ValueError when that cannot be done (a run going,
    an unknown protocol); a parameter the protocol no longer has is skipped and named."""
    if panel.busy:
        raise ValueError("a run is going: the Protocols tab cannot be changed now")
    index = panel.protocol_combo.findData(protocol)
    if index < 0:
        raise ValueError(f"this rigctl has no protocol {protocol!r} (the run's)")
    panel.protocol_combo.setCurrentIndex(index)
    skipped = []
    for name, value in parameters.items():
        try:
            panel.set_param(name, parameter_text(value))
        except KeyError:
            skipped.append(name)
    text = f"Protocols tab set to {protocol} with the run's {len(parameters) - len(skipped)} parameters"
    return text + (f"; not in the protocol any more: {', '.join(skipped)}" if skipped else "")


class RunsPanel(QWidget):
    """Open a run; plots, events, status, parameters, configuration; export; run again; analyse."""

    run_again = Signal(str, object)
    """(protocol, parameters): "run again with these parameters" was pressed."""
    status_message = Signal(str)
    """One line for the main window's status bar (errors and what was done)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.path: Path | None = None
        self.kind = ""
        """``"h5"`` or ``"csv"`` for the open run, ``""`` before one is opened."""
        self.status = ""
        self.samples_read = 0
        self.summary: dict[str, Any] = {}
        self.report: AnalysisDone | None = None
        self._reader: Any = None
        self._read_failures = 0
        self._envelope = PeakEnvelope("ft_N", OVERVIEW_POINTS)
        self._protocol = ""
        self._parameters: dict[str, Any] = {}
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.timeout.connect(self._read_more)
        self.job = ProcessJob(self)
        self.job.progress.connect(self._on_job_progress)
        self.job.finished.connect(self._on_report)
        self.job.failed.connect(lambda msg: self._error(f"analysis failed: {msg}"))
        self.job.cancelled.connect(self._on_job_cancelled)
        self._build()
        self._set_actions()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        self.open_button = QPushButton("Open run…")
        self.open_button.setToolTip("an HDF5 run file (also one being recorded) or a CSV run")
        self.open_button.clicked.connect(self._browse)
        self.export_button = QPushButton("Export CSV…")
        self.export_button.setToolTip("the run's samples and provenance as exchange-format CSV "
                                      "(as rigctl export)")
        self.export_button.clicked.connect(self._browse_export)
        self.again_button = QPushButton("Run again with these parameters")
        self.again_button.setToolTip("fill the Protocols tab with this run's protocol and parameters")
        self.again_button.clicked.connect(self._emit_run_again)
        self.analyse_button = QPushButton("Analysis report")
        self.analyse_button.setToolTip("rigctl analyse: stages, cycles, friction, stiffness (HTML)")
        self.analyse_button.clicked.connect(lambda: self.analyse())
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.job.cancel)
        self.open_report_button = QPushButton("Open report")
        self.open_report_button.clicked.connect(self._open_report)
        buttons = QHBoxLayout()
        for b in (self.open_button, self.export_button, self.again_button, self.analyse_button,
                  self.cancel_button, self.open_report_button):
            buttons.addWidget(b)
        buttons.addStretch(1)
        self.path_label = QLabel("no run open")
        self.path_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_label = QLabel("")
        self.status_label.setWordWrap(True)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setTextVisible(True)
        self.progress.setFormat("")
        self.progress.setMaximumHeight(16)
        self.progress.setMinimumWidth(260)
        self.progress.setVisible(False)  # shown from the first analysis on

        self.glw = pg.GraphicsLayoutWidget()
        self.glw.setBackground("w")
        self.ft_plot = self._plot(0, "Ft", "N")
        self.fn_plot = self._plot(1, "Fn", "N")
        self.delta_plot = self._plot(2, "delta", "m")
        self.delta_plot.setLabel("bottom", "time (s)")
        self.delta_plot.getAxis("bottom").enableAutoSIPrefix(False)
        for p in (self.ft_plot, self.fn_plot):
            p.setXLink(self.delta_plot)
            p.getAxis("bottom").setStyle(showValues=False)
        self.loop_plot = self.glw.addPlot(row=0, col=1, rowspan=3)
        self.loop_plot.setLabel("bottom", "delta", units="m")
        self.loop_plot.setLabel("left", "Ft", units="N")
        self.loop_plot.showGrid(x=True, y=True, alpha=0.3)
        self.glw.ci.layout.setColumnStretchFactor(0, 3)
        self.glw.ci.layout.setColumnStretchFactor(1, 2)
        self.ft_curve = self._curve(self.ft_plot, _BLUE)
        self.fn_curve = self._curve(self.fn_plot, _RED)
        self.delta_curve = self._curve(self.delta_plot, _GREEN)
        self.loop_curve = self._curve(self.loop_plot, _BLUE)
        self._event_lines: list[pg.InfiniteLine] = []

        self.info_table = _table(("field", "value"))
        self.events_table = _table(("t (s)", "event", "message"))
        self.params_table = _table(("parameter", "value"))
        self.config_view = QPlainTextEdit()
        self.config_view.setReadOnly(True)
        mono = QFont("monospace")
        mono.setStyleHint(QFont.StyleHint.Monospace)
        mono.setPointSize(8)
        self.config_view.setFont(mono)
        self.report_view = QPlainTextEdit()
        self.report_view.setReadOnly(True)
        self.report_view.setPlaceholderText("Analysis report: press 'Analysis report'")
        self.figure_label = QLabel()
        self.figure_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        report_page = QWidget()
        rl = QVBoxLayout(report_page)
        rl.setContentsMargins(0, 0, 0, 0)
        rl.addWidget(self.report_view, 1)
        rl.addWidget(self.figure_label, 2)
        self.details = QTabWidget()
        self.details.addTab(self.info_table, "Status")
        self.details.addTab(self.events_table, "Events")
        self.details.addTab(self.params_table, "Parameters")
        self.details.addTab(self.config_view, "Configuration")
        self.details.addTab(report_page, "Report")

        self.log = QPlainTextEdit()
        self.log.setReadOnly(True)
        self.log.setMaximumBlockCount(2000)
        self.log.setPlaceholderText("log: what was opened, exported, analysed, and every error")
        self.log.setMaximumHeight(90)

        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(self.glw)
        split.addWidget(self.details)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        split.setSizes([700, 560])
        top = QVBoxLayout(self)
        top.addLayout(buttons)
        row = QHBoxLayout()
        row.addWidget(self.path_label, 1)
        row.addWidget(self.progress)
        top.addLayout(row)
        top.addWidget(self.status_label)
        top.addWidget(split, 1)
        top.addWidget(self.log)

    def _plot(self, row: int, name: str, unit: str) -> pg.PlotItem:
        p = self.glw.addPlot(row=row, col=0)
        p.setLabel("left", name, units=unit)
        p.showGrid(x=True, y=True, alpha=0.3)
        return p

    @staticmethod
    def _curve(plot: pg.PlotItem, color: str) -> pg.PlotCurveItem:
        curve = pg.PlotCurveItem(pen=pg.mkPen(color, width=1))
        plot.addItem(curve)
        return curve

    def _set_actions(self) -> None:
        busy = self.job.running
        h5 = self.kind == "h5"
        self.export_button.setEnabled(h5 and self.samples_read > 0)
        self.again_button.setEnabled(bool(self._protocol) and bool(self._parameters))
        self.analyse_button.setEnabled(bool(self.kind) and not busy and self.samples_read > 0)
        self.cancel_button.setEnabled(busy)
        self.open_report_button.setEnabled(self.report is not None)

    # ------------------------------------------------------------------ log and status
    def _say(self, text: str) -> None:
        self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}  {text}")
        self.status_message.emit(text)

    def _error(self, text: str) -> None:
        self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}  ERROR {text}")
        self.status_message.emit(f"error: {text}")
        self.status_label.setText(text)
        self.status_label.setStyleSheet(f"color: {_RED}; font-weight: bold")
        self.progress.setRange(0, 1000)
        self.progress.setFormat("")
        self._set_actions()

    # ------------------------------------------------------------------ opening
    def _browse(self) -> None:
        name, _ = QFileDialog.getOpenFileName(self, "Open a run", "",
                                              "runs (*.h5 *.hdf5 *.csv);;all files (*)")
        if name:
            self.open(name)

    def open(self, path: str | Path) -> bool:
        """Open a run (``.h5``/``.hdf5`` or ``.csv``); False (and the reason in the log) if not."""
        from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES

        self.close_run()
        p = Path(path)
        suffix = p.suffix.lower()
        try:
            if suffix in RUN_FILE_SUFFIXES:
                self._open_h5(p)
            elif suffix in CSV_SUFFIXES:
                self._open_csv(p)
            else:
                raise ValueError(f"expected a {' or '.join(RUN_FILE_SUFFIXES + CSV_SUFFIXES)} file")
        except Exception as exc:
            self.close_run()
            self._error(f"cannot open {p}: {exc}")
            return False
        self._say(f"opened {p} ({self.status})")
        self._set_actions()
        return True

    def close_run(self) -> None:
        """Forget the open run (the file is released)."""
        self._timer.stop()
        if self._reader is not None:
            reader, self._reader = self._reader, None
            reader.close()
        self.path, self.kind, self.status, self.samples_read = None, "", "", 0
        self.summary, self._protocol, self._parameters = {}, "", {}
        self.report = None
        self._envelope = PeakEnvelope("ft_N", OVERVIEW_POINTS)
        for c in (self.ft_curve, self.fn_curve, self.delta_curve, self.loop_curve):
            c.setData([], [])
        for line in self._event_lines:
            self.ft_plot.removeItem(line)
        self._event_lines = []
        for t in (self.info_table, self.events_table, self.params_table):
            t.setRowCount(0)
        self.config_view.clear()
        self.report_view.clear()
        self.figure_label.clear()
        self.path_label.setText("no run open")
        self.status_label.setText("")
        self.status_label.setStyleSheet("")
        self._set_actions()

    def _open_h5(self, p: Path) -> None:
        from rigctl.storage import RunReader

        self._reader = RunReader(p)
        self.path, self.kind = p, "h5"
        missing = [c for c in ("ft_N", "fn_N", "d1_m", "d2_m") if c not in self._reader.channels]
        if missing:
            raise ValueError(f"the run has no channel(s) {', '.join(missing)}")
        self.config_view.setPlainText(self._reader.config_toml or "(no configuration recorded)")
        self._protocol = self._reader.protocol
        self._parameters = dict(self._reader.parameters)
        _fill_table(self.params_table, [(k, parameter_text(v)) for k, v in self._parameters.items()])
        self._read_more()

    def _open_csv(self, p: Path) -> None:
        from rigctl.io.load import load_run

        run = load_run(p)
        self.path, self.kind = p, "csv"
        self._append(self._columns_of(run))
        meta = run.metadata
        self.status = meta.get("run.status", "csv (no recording status)")
        self._protocol = meta.get("run.protocol", meta.get("protocol", ""))
        self._parameters = {}
        self.summary = {"file": str(p), "protocol": self._protocol or "-", "status": self.status,
                        "samples": f"{run.n_samples} at {run.sample_rate_hz:.6g} Hz",
                        "duration": f"{run.duration_s:.6g} s",
                        "channels": ", ".join(c for c in run.columns() if c != "t_s")}
        self.summary.update({f"# {k}": v for k, v in meta.items()})
        _fill_table(self.info_table, [(k, str(v)) for k, v in self.summary.items()])
        self.config_view.setPlainText("(a CSV run carries no rig configuration; its '# key: value' "
                                      "lines are under Status)")
        self._show_status()
        self._redraw()

    @staticmethod
    def _columns_of(run: MeasuredRun) -> dict[str, np.ndarray]:
        return {"t_s": run.t_s, "ft_N": run.ft_N, "fn_N": run.fn_N, "delta_m": run.delta_m}

    # ------------------------------------------------------------------ following an HDF5 run
    def _read_more(self) -> None:
        """One tick: new samples (at most READ_CHUNK), status, events; schedules the next tick."""
        reader = self._reader
        if reader is None:
            return
        try:
            n = reader.refresh()
            status = reader.status
            stop = min(n, self.samples_read + READ_CHUNK)
            if stop > self.samples_read:
                cols = reader.read_daq(self.samples_read, stop)
                self._append({"t_s": cols["t_s"], "ft_N": cols["ft_N"], "fn_N": cols["fn_N"],
                              "delta_m": cols["d1_m"] - cols["d2_m"]})
                self.samples_read = stop
            behind = self.samples_read < n
            if not behind or status != self.status:
                self._show_h5_details(reader, status)
        except Exception as exc:
            self._read_failures += 1
            if self.status == RunStatus.RUNNING and self._read_failures < MAX_READ_FAILURES:
                self._say(f"reading {self.path} (being written): {exc}; trying again")
                self._timer.start(FOLLOW_INTERVAL_MS)
            else:
                self._error(f"reading {self.path}: {exc}")
            return
        self._read_failures = 0
        self._redraw()
        if behind:
            self._timer.start(0)
        elif status == RunStatus.RUNNING:
            self._timer.start(FOLLOW_INTERVAL_MS)
        else:  # closed and all read: release the file
            self._reader = None
            reader.close()
        self._set_actions()

    def _append(self, cols: dict[str, np.ndarray]) -> None:
        self._envelope.append(cols)

    def _show_h5_details(self, reader: Any, status: str) -> None:
        s = reader.summary()
        self.status = status
        self.summary = {
            "file": s.path, "protocol": s.protocol, "status": status, "error": s.error or "-",
            "start": s.start_time or "-", "end": s.end_time or "-",
            "duration": f"{s.duration_s:.6g} s",
            "samples": f"{s.n_samples} at {s.sample_rate_hz:.6g} Hz",
            "channels": ", ".join(f"{k} [{u or '-'}]" for k, u in s.channels.items()),
            "dropped": f"{s.dropped_samples} samples, {s.dropped_frames} frames",
            "events": str(s.n_events), "frames": str(s.n_frames),
            "operator": s.operator or "-", "notes": s.notes or "-",
            "software": ", ".join(f"{k} {v}" for k, v in s.software.items()),
        }
        _fill_table(self.info_table, list(self.summary.items()))
        events = reader.events()
        _fill_table(self.events_table, [(f"{e.t_s:.3f}", e.name, e.message) for e in events])
        for line in self._event_lines:
            self.ft_plot.removeItem(line)
        self._event_lines = []
        for e in events:
            line = pg.InfiniteLine(e.t_s, angle=90, pen=pg.mkPen("#9e9e9e", width=1,
                                                                style=Qt.PenStyle.DashLine))
            line.setToolTip(f"{e.name}: {e.message}")
            self.ft_plot.addItem(line)
            self._event_lines.append(line)
        self._show_status()

    def _show_status(self) -> None:
        text = self.status
        colors: dict[str, str] = {RunStatus.COMPLETED: _GREEN, RunStatus.RUNNING: _BLUE}
        color = colors.get(self.status, _ORANGE)
        if self.status == RunStatus.RUNNING:
            text = "running: being recorded (following it; new samples every 2 s)"
        elif self.summary.get("error", "-") not in ("-", ""):
            text += f": {self.summary['error']}"
        self.status_label.setText(f"{'HDF5' if self.kind == 'h5' else 'CSV'} run, status {text}")
        self.status_label.setStyleSheet(f"color: {color}; font-weight: bold")
        self.path_label.setText(str(self.path))

    def _redraw(self) -> None:
        v = self._envelope.view()
        if not v or len(v["t_s"]) == 0:
            return
        self.ft_curve.setData(v["t_s"], v["ft_N"])
        self.fn_curve.setData(v["t_s"], v["fn_N"])
        self.delta_curve.setData(v["t_s"], v["delta_m"])
        self.loop_curve.setData(v["delta_m"], v["ft_N"])
        self.ft_plot.setTitle(f"{self._envelope.n_samples:,} samples "
                              f"(overview: {len(v['t_s']):,} points, each bin's min and max Ft)",
                              size="8pt")

    @property
    def plotted_points(self) -> int:
        d = self.ft_curve.getData()[0]
        return 0 if d is None else len(d)

    # ------------------------------------------------------------------ actions
    def _emit_run_again(self) -> None:
        if self._protocol and self._parameters:
            self.run_again.emit(self._protocol, dict(self._parameters))

    def _browse_export(self) -> None:
        if self.path is None:
            return
        name, _ = QFileDialog.getSaveFileName(self, "Export to CSV",
                                              str(self.path.with_suffix(".csv")), "CSV (*.csv)")
        if name:
            self.export_csv(name, force=True)  # the dialog asked about replacing

    def export_csv(self, csv_path: str | Path, *, force: bool = False) -> bool:
        """Export the open HDF5 run (as ``rigctl export``); False and the reason logged if refused."""
        from rigctl.io.export import export_csv
        from rigctl.io.outputs import check_output_file

        if self.path is None or self.kind != "h5":
            self._error("export: open an HDF5 run first")
            return False
        out = Path(csv_path)
        try:
            if out.suffix.lower() != ".csv":
                raise ValueError(f"{out}: expected a .csv file")
            check_output_file(out, "CSV", force=force)
            run = export_csv(self.path, out)
        except Exception as exc:
            self._error(f"export: {exc}")
            return False
        note = " (the run is still being recorded: what was written so far)" if (
            self.status == RunStatus.RUNNING) else ""
        self._say(f"exported {out} ({run.n_samples} samples, {len(run.columns())} columns){note}")
        return True

    def analyse(self, out_dir: str | Path | None = None) -> bool:
        """Start ``rigctl analyse`` on the open run in a worker process (report folder: ``out_dir``,
        default ``analysis_<run name>`` next to the run)."""
        if self.path is None:
            self._error("analysis: open a run first")
            return False
        if self.job.running:
            self._error("analysis: one is already running")
            return False
        out = Path(out_dir) if out_dir is not None else default_report_folder(self.path)
        self.report = None
        self.report_view.setPlainText(f"analysing {self.path} into {out} …")
        self.figure_label.clear()
        self.progress.setVisible(True)
        self.progress.setRange(0, 0)
        self.progress.setFormat("analysis")
        try:
            self.job.start("analyse", analyse_job, str(self.path), str(out))
        except Exception as exc:
            self._error(f"analysis could not start: {exc}")
            return False
        self._say(f"analysis of {self.path.name} started (report in {out})")
        self._set_actions()
        return True

    def _on_job_progress(self, text: str, fraction: float) -> None:
        if math.isfinite(fraction):
            self.progress.setRange(0, 1000)
            self.progress.setValue(round(1000 * fraction))
        self.progress.setFormat(text)
        self.report_view.appendPlainText(text)

    def _on_report(self, done: AnalysisDone) -> None:
        self.report = done
        self.progress.setRange(0, 1000)
        self.progress.setValue(1000)
        self.progress.setFormat("report written")
        lines = [f"report: {done.index}", f"numbers: {done.json_path}", *done.lines,
                 "figures:", *(f"  {f}" for f in done.figures)]
        self.report_view.setPlainText("\n".join(lines))
        first = next((f for f in done.figures if Path(f).name == "ft_time.png"), None) or (
            done.figures[0] if done.figures else None)
        if first is not None:
            pix = QPixmap(first)
            self.figure_label.setPixmap(pix.scaledToWidth(
                min(pix.width(), 560), Qt.TransformationMode.SmoothTransformation))
        self.details.setCurrentIndex(self.details.count() - 1)
        self._say(f"analysis report written: {done.index}")
        self._set_actions()

    def _on_job_cancelled(self) -> None:
        self.progress.setRange(0, 1000)
        self.progress.setValue(0)
        self.progress.setFormat("cancelled")
        self._say("analysis cancelled")
        self._set_actions()

    def _open_report(self) -> None:
        if self.report is not None:
            QDesktopServices.openUrl(QUrl.fromLocalFile(self.report.index))

    def shutdown(self) -> None:
        """Stop the analysis (if any) and release the run file."""
        self.job.cancel()
        self.close_run()

