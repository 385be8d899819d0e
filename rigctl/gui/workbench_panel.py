"""The Workbench tab: compare the physics model with measured runs and find what it is missing.

Pick runs (``.h5``/``.csv``) or a campaign folder; **Compare** identifies the model (base + the
effects added so far) on them and shows measurement against model (Ft against time, Ft against delta),
the residual map (how each slip feature's misfit trends with each covariate) and where the model
fails, in words. **Rank candidates** fits every effect of the library and the plug-ins on top of the
model and ranks them by evidence (``rigctl model diagnose``); each plug-in candidate's fitted
parameters appear under the ranking as its fit ends, with their uncertainties once the round is
over. **Add effect** (a library effect, or one
of a plug-in file loaded with **Plug-in file…**) re-identifies the model with it; the error history
chart shows the error after each step, falling as the right effects are added.

Every fit runs in a worker process (:mod:`rigctl.gui.process_job`, jobs in
:mod:`rigctl.gui.workbench_jobs`) with its progress shown and a Cancel button; the window never
waits. Errors go to the tab's log and :attr:`WorkbenchPanel.status_message` (the status bar).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QListWidget,
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

from rigctl.gui.process_job import ProcessJob
from rigctl.gui.workbench_jobs import (
    CandidateParams,
    CompareView,
    DiagnoseView,
    ModelRequest,
    compare_job,
    diagnose_job,
)

_MEAS, _MODEL, _RED, _GREEN = "#424242", "#d62728", "#c62828", "#2e7d32"


def _item(text: str, tip: str = "") -> QTableWidgetItem:
    item = QTableWidgetItem(text)
    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
    if tip:
        item.setToolTip(tip)
    return item


def _z_colour(z: float, zmax: float) -> QColor:
    """White at 0, red for positive, blue for negative trends (the HTML report's RdBu scale)."""
    a = min(abs(z) / zmax, 1.0) if zmax > 0 else 0.0
    r, g, b = (214, 96, 77) if z > 0 else (67, 147, 195)
    return QColor(round(255 + a * (r - 255)), round(255 + a * (g - 255)), round(255 + a * (b - 255)))


def _short(feature: str) -> str:
    """A feature's name without its unit suffix (``k_stick_N_per_m`` -> ``k_stick``)."""
    for suffix in ("_N_per_m", "_N_per_s", "_N", "_s", "_m"):
        if feature.endswith(suffix):
            return feature[: -len(suffix)]
    return feature


class WorkbenchPanel(QWidget):
    """Data, model, compare, rank, add effect, error history; fits in worker processes."""

    status_message = Signal(str)

    def __init__(self, parent: QWidget | None = None, *, workers: int | None = None) -> None:
        super().__init__(parent)
        self.request = ModelRequest(())
        self.workers = workers
        self.history: list[tuple[str, float]] = []
        """(model, error) after each compare: the error history chart."""
        self.view: CompareView | None = None
        self.diagnosis: DiagnoseView | None = None
        self.plugin_params: dict[str, CandidateParams] = {}
        """Each plug-in candidate's fitted parameters, as they arrived (during a round) or with
        their uncertainties (after it)."""
        self.job = ProcessJob(self)
        self.job.progress.connect(self._on_progress)
        self.job.finished.connect(self._on_finished)
        self.job.failed.connect(self._on_failed)
        self.job.cancelled.connect(self._on_cancelled)
        self._pending: ModelRequest | None = None
        self._build()
        self._fill_effects()
        self._set_actions()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        self.add_runs_button = QPushButton("Add runs…")
        self.add_runs_button.clicked.connect(self._browse_runs)
        self.add_folder_button = QPushButton("Add campaign folder…")
        self.add_folder_button.clicked.connect(self._browse_folder)
        self.clear_button = QPushButton("Clear data")
        self.clear_button.clicked.connect(lambda: self.set_data([]))
        self.data_list = QListWidget()
        self.data_list.setMaximumHeight(64)
        self.base_combo = QComboBox()
        self.base_combo.addItems(["paper", "classic"])
        self.base_combo.setToolTip("base model: the paper's (Han et al. 2022) or the classic one")
        self.base_combo.currentTextChanged.connect(self._base_changed)
        self.model_label = QLabel()
        self.model_label.setStyleSheet("font-weight: bold")
        self.compare_button = QPushButton("Compare")
        self.compare_button.setToolTip("identify the model on the data and compare (rigctl model "
                                       "compare)")
        self.compare_button.clicked.connect(lambda: self.compare())
        self.rank_button = QPushButton("Rank candidates")
        self.rank_button.setToolTip("fit every library and plug-in effect on top of the model and "
                                    "rank them by evidence (rigctl model diagnose)")
        self.rank_button.clicked.connect(lambda: self.rank())
        self.effect_combo = QComboBox()
        self.effect_combo.setMinimumContentsLength(22)
        self.add_effect_button = QPushButton("Add effect")
        self.add_effect_button.setToolTip("add the chosen effect to the model and re-identify it")
        self.add_effect_button.clicked.connect(lambda: self.add_effect())
        self.plugin_button = QPushButton("Plug-in file…")
        self.plugin_button.setToolTip("a Python file of Effect classes (docs/workbench.md)")
        self.plugin_button.clicked.connect(self._browse_plugin)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.job.cancel)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setFormat("")
        self.progress.setMinimumWidth(260)

        data_row = QHBoxLayout()
        col = QVBoxLayout()
        for b in (self.add_runs_button, self.add_folder_button, self.clear_button):
            col.addWidget(b)
        data_row.addLayout(col)
        data_row.addWidget(self.data_list, 1)
        model_row = QHBoxLayout()
        model_row.addWidget(QLabel("Base"))
        model_row.addWidget(self.base_combo)
        model_row.addWidget(QLabel("Model:"))
        model_row.addWidget(self.model_label, 1)
        model_row.addWidget(self.compare_button)
        model_row.addWidget(self.rank_button)
        model_row.addWidget(self.effect_combo)
        model_row.addWidget(self.add_effect_button)
        model_row.addWidget(self.plugin_button)
        job_row = QHBoxLayout()
        job_row.addWidget(self.progress, 1)
        job_row.addWidget(self.cancel_button)

        self.glw = pg.GraphicsLayoutWidget()
        self.glw.setBackground("w")
        self.time_plot = self.glw.addPlot(row=0, col=0, colspan=2)
        self.time_plot.setLabel("left", "Ft", units="N")
        self.time_plot.setLabel("bottom", "time from the run's start (s)")
        self.time_plot.getAxis("bottom").enableAutoSIPrefix(False)
        self.time_plot.showGrid(x=True, y=True, alpha=0.3)
        self.time_plot.addLegend(offset=(-10, -10))
        self.meas_curve = pg.PlotCurveItem(pen=pg.mkPen(_MEAS, width=1), name="measured")
        self.model_curve = pg.PlotCurveItem(pen=pg.mkPen(_MODEL, width=1), name="model")
        self.time_plot.addItem(self.meas_curve)
        self.time_plot.addItem(self.model_curve)
        self.loop_plot = self.glw.addPlot(row=1, col=0)
        self.loop_plot.setLabel("left", "Ft", units="N")
        self.loop_plot.setLabel("bottom", "delta", units="m")
        self.loop_plot.showGrid(x=True, y=True, alpha=0.3)
        self.meas_loop = pg.PlotCurveItem(pen=pg.mkPen(_MEAS, width=1))
        self.model_loop = pg.PlotCurveItem(pen=pg.mkPen(_MODEL, width=1))
        self.loop_plot.addItem(self.meas_loop)
        self.loop_plot.addItem(self.model_loop)
        self.history_plot = self.glw.addPlot(row=1, col=1)
        self.history_plot.setLabel("left", "error E (log scale)")
        self.history_plot.getAxis("left").setTicks([[(math.log10(v), f"{v:g}") for v in (
            0.001, 0.01, 0.1, 1.0, 10.0, 100.0, 1000.0, 1e4)], [(math.log10(v), f"{v:g}") for v in (
            0.003, 0.03, 0.3, 3.0, 30.0, 300.0, 3000.0)]])
        self.history_plot.showGrid(x=False, y=True, alpha=0.3)
        self.history_plot.setTitle("error history (dotted: measurement scatter)", size="9pt")
        self.history_curve = pg.PlotDataItem(pen=pg.mkPen(_MODEL, width=2), symbol="o",
                                             symbolBrush=_MODEL, symbolSize=8)
        self.history_plot.addItem(self.history_curve)
        self.history_plot.addItem(pg.InfiniteLine(0.0, angle=0, pen=pg.mkPen(
            "#888888", style=Qt.PenStyle.DotLine)))
        self._history_labels: list[pg.TextItem] = []
        self.run_combo = QComboBox()
        self.run_combo.setToolTip("the run shown in the overlays")
        self.run_combo.currentIndexChanged.connect(self._show_overlay)
        plots = QWidget()
        pl = QVBoxLayout(plots)
        pl.setContentsMargins(0, 0, 0, 0)
        pl.addWidget(self.run_combo)
        pl.addWidget(self.glw, 1)

        self.residual_table = QTableWidget(0, 0)
        self.residual_table.setWordWrap(False)
        self.residual_table.horizontalHeader().setStyleSheet("QHeaderView { font-size: 8pt; }")
        self.residual_table.setToolTip("trend of each slip feature's misfit (z, model - measured) "
                                       "with each covariate; |t| < 3 shown blank")
        self.ranking_table = QTableWidget(0, 6)
        self.ranking_table.setHorizontalHeaderLabels(
            ["effect", "error", "reduction", "ΔBIC", "significant", "explains"])
        self.ranking_table.verticalHeader().setVisible(False)
        self.ranking_table.horizontalHeader().setStretchLastSection(True)
        self.ranking_table.itemSelectionChanged.connect(self._ranking_selected)
        self.verdict_label = QLabel()
        self.verdict_label.setWordWrap(True)
        self.plugin_label = QLabel("<b>Plug-in candidates: fitted parameters</b> (± 1 sigma; "
                                   "±? until the round ends and the uncertainties are taken)")
        self.plugin_label.setWordWrap(True)
        self.plugin_table = QTableWidget(0, 4)
        self.plugin_table.setHorizontalHeaderLabels(["plug-in", "parameter", "value ± sigma",
                                                     "fit error"])
        self.plugin_table.verticalHeader().setVisible(False)
        self.plugin_table.horizontalHeader().setStretchLastSection(True)
        self.plugin_table.setToolTip("each plug-in candidate's own parameters as its fit ends "
                                     "(base parameters fitted with them); the 1-sigma uncertainty "
                                     "from the linearised covariance at the fitted values, taken "
                                     "after the round")
        ranking_page = QWidget()
        rl = QVBoxLayout(ranking_page)
        rl.setContentsMargins(0, 0, 0, 0)
        rl.addWidget(self.verdict_label)
        rl.addWidget(self.ranking_table, 3)
        rl.addWidget(self.plugin_label)
        rl.addWidget(self.plugin_table, 2)
        self._show_plugin_params()
        self.params_table = QTableWidget(0, 3)
        self.params_table.setHorizontalHeaderLabels(["parameter", "value ± sigma", "unit"])
        self.params_table.verticalHeader().setVisible(False)
        self.params_table.horizontalHeader().setStretchLastSection(True)
        self.fails_view = QPlainTextEdit()
        self.fails_view.setReadOnly(True)
        self.details = QTabWidget()
        self.details.addTab(self.residual_table, "Residual map")
        self.details.addTab(ranking_page, "Ranking")
        self.details.addTab(self.fails_view, "Where it fails")
        self.details.addTab(self.params_table, "Parameters")

        self.log = QPlainTextEdit()
        self.log.setReadOnly(True)
        self.log.setMaximumBlockCount(2000)
        self.log.setMaximumHeight(90)
        self.log.setPlaceholderText("log: the fits' progress and every error")

        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(plots)
        split.addWidget(self.details)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        split.setSizes([640, 620])
        top = QVBoxLayout(self)
        top.addLayout(data_row)
        top.addLayout(model_row)
        top.addLayout(job_row)
        top.addWidget(split, 1)
        top.addWidget(self.log)

    # ------------------------------------------------------------------ state
    def _set_actions(self) -> None:
        busy = self.job.running
        has_data = bool(self.request.paths)
        for b in (self.add_runs_button, self.add_folder_button, self.clear_button, self.base_combo,
                  self.plugin_button):
            b.setEnabled(not busy)
        self.compare_button.setEnabled(has_data and not busy)
        self.rank_button.setEnabled(has_data and not busy and self.effect_combo.count() > 0)
        self.add_effect_button.setEnabled(has_data and not busy and self.effect_combo.count() > 0)
        self.effect_combo.setEnabled(not busy)
        self.cancel_button.setEnabled(busy)
        self.model_label.setText(self.request.label())

    def _say(self, text: str) -> None:
        self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}  {text}")
        self.status_message.emit(text)

    def _error(self, text: str) -> None:
        self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}  ERROR {text}")
        self.status_message.emit(f"error: {text}")

    def _fill_effects(self) -> None:
        """The effects the model could get: the library's and the plug-ins', minus those it has."""
        from rigctl.workbench.model_choice import ModelChoice, candidate_effects

        r = self.request
        names = candidate_effects(ModelChoice(r.base, r.effects, {}, r.effect_files))
        current = self.effect_combo.currentText()
        self.effect_combo.clear()
        self.effect_combo.addItems(names)
        if current in names:
            self.effect_combo.setCurrentText(current)

    # ------------------------------------------------------------------ data and model
    def _browse_runs(self) -> None:
        names, _ = QFileDialog.getOpenFileNames(self, "Runs to compare with the model", "",
                                                "runs (*.h5 *.hdf5 *.csv)")
        if names:
            self.set_data([*self.request.paths, *names])

    def _browse_folder(self) -> None:
        name = QFileDialog.getExistingDirectory(self, "A campaign folder")
        if name:
            self.set_data([*self.request.paths, name])

    def set_data(self, paths: list[str] | tuple[str, ...]) -> None:
        """The runs and folders to work on; the model's history starts again."""
        missing = [p for p in paths if not Path(p).exists()]
        if missing:
            self._error(f"no such file or folder: {', '.join(missing)}")
            paths = [p for p in paths if Path(p).exists()]
        self.request = replace(self.request, paths=tuple(str(p) for p in paths), effects=())
        self.data_list.clear()
        self.data_list.addItems(list(self.request.paths))
        self._reset_results()
        self._fill_effects()
        self._set_actions()
        if paths:
            self._say(f"data: {len(paths)} path(s); press Compare")

    def _base_changed(self, base: str) -> None:
        self.request = replace(self.request, base=base, effects=())
        self._reset_results()
        self._fill_effects()
        self._set_actions()

    def _reset_results(self) -> None:
        self.history.clear()
        self.view = None
        self.diagnosis = None
        self._show_history()
        self.ranking_table.setRowCount(0)
        self.verdict_label.clear()
        for c in (self.meas_curve, self.model_curve, self.meas_loop, self.model_loop):
            c.setData([], [])
        self.residual_table.setRowCount(0)
        self.fails_view.clear()
        self.params_table.setRowCount(0)
        self.plugin_params.clear()
        self._show_plugin_params()
        self.run_combo.clear()

    def _browse_plugin(self) -> None:
        name, _ = QFileDialog.getOpenFileName(self, "A plug-in effect file", "", "Python (*.py)")
        if name:
            self.load_plugin(name)

    def load_plugin(self, path: str | Path) -> list[str]:
        """Make a plug-in file's effects available (as ``--effect-file``); their names."""
        from rigctl.workbench.model_choice import registry_for

        p = str(Path(path).resolve())
        try:
            if not Path(p).is_file():
                raise ValueError("no such file")
            before = set(registry_for(self.request.effect_files))
            files = (*self.request.effect_files, p) if p not in self.request.effect_files else (
                self.request.effect_files)
            new = sorted(set(registry_for(files)) - before)
        except Exception as exc:
            self._error(f"plug-in {path}: {exc}")
            return []
        self.request = replace(self.request, effect_files=files)
        self._fill_effects()
        if new:
            self.effect_combo.setCurrentText(new[0])
        self._set_actions()
        self._say(f"plug-in {Path(p).name}: {', '.join(new) or 'no new effects'}")
        return new

    # ------------------------------------------------------------------ jobs
    def compare(self, request: ModelRequest | None = None) -> bool:
        """Identify and compare ``request`` (default: the current model) in a worker process."""
        req = request or self.request
        if not req.paths:
            self._error("compare: add runs or a campaign folder first")
            return False
        if self.job.running:
            self._error(f"{self.job.name} is still running (wait or cancel it)")
            return False
        self._pending = req
        self._start(f"compare {req.label()}", compare_job, req)
        return True

    def add_effect(self, name: str | None = None) -> bool:
        """Add an effect (default: the one chosen) and re-identify the model with it."""
        effect = name or self.effect_combo.currentText()
        if not effect:
            self._error("add effect: choose an effect first")
            return False
        if effect in self.request.effects:
            self._error(f"add effect: the model already has {effect}")
            return False
        return self.compare(replace(self.request, effects=(*self.request.effects, effect)))

    def rank(self, candidates: tuple[str, ...] = ()) -> bool:
        """Rank candidate effects on the current model (default: all it could get)."""
        if not self.request.paths:
            self._error("rank: add runs or a campaign folder first")
            return False
        if self.job.running:
            self._error(f"{self.job.name} is still running (wait or cancel it)")
            return False
        self._pending = None
        self.plugin_params.clear()
        self._show_plugin_params()
        self._start(f"rank candidates on {self.request.label()}", diagnose_job, self.request,
                    candidates, self.workers)
        return True

    def _start(self, name: str, target: Callable[..., Any], *args: Any) -> None:
        self.progress.setRange(0, 0)
        self.progress.setFormat(name)
        try:
            self.job.start(name, target, *args)
        except Exception as exc:
            self._job_over(f"{name}: not started")
            self._error(f"{name} could not start: {exc}")
            return
        self._say(f"{name}: started in a worker process")
        self._set_actions()

    def cancel(self) -> bool:
        return self.job.cancel()

    def _on_progress(self, text: str, fraction: float) -> None:
        params = CandidateParams.from_text(text)
        if params is not None:  # a plug-in candidate's parameters, not a line of progress
            self.plugin_params[params.effect] = params
            self._show_plugin_params()
            self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}    {params.line()}")
            return
        if math.isfinite(fraction):
            self.progress.setRange(0, 1000)
            self.progress.setValue(round(1000 * fraction))
        self.progress.setFormat(text[:120])
        self.log.appendPlainText(f"{time.strftime('%H:%M:%S')}    {text}")

    def _job_over(self, text: str) -> None:
        self.progress.setRange(0, 1000)
        self.progress.setValue(1000 if text.endswith("done") else 0)
        self.progress.setFormat(text)
        self._set_actions()

    def _on_failed(self, message: str) -> None:
        name = self.job.name
        self._pending = None
        self._job_over(f"{name}: failed")
        self._error(f"{name}: {message}")

    def _on_cancelled(self) -> None:
        self._pending = None
        self._job_over(f"{self.job.name}: cancelled")
        self._say(f"{self.job.name}: cancelled (the worker process was stopped)")

    def _on_finished(self, result: object) -> None:
        if isinstance(result, CompareView):
            if self._pending is not None:
                self.request = self._pending
            self._pending = None
            self._show_compare(result)
        elif isinstance(result, DiagnoseView):
            self._show_ranking(result)
        self._fill_effects()
        self._job_over(f"{self.job.name}: done")

    # ------------------------------------------------------------------ showing results
    def _show_compare(self, v: CompareView) -> None:
        previous = self.history[-1][1] if self.history else math.nan
        self.view = v
        self.history.append((v.label, v.error))
        self._show_history()
        self.run_combo.blockSignals(True)
        self.run_combo.clear()
        self.run_combo.addItems([o.name for o in v.overlays])
        self.run_combo.blockSignals(False)
        self._show_overlay(0)
        self._show_residual(v)
        lines = [f"model {v.label}: error {v.error:.3g} ({v.n_events} slip events in {v.n_runs} "
                 f"run(s))", ""]
        lines += [f"- {d}" for d in v.discrepancies] or ["no structured discrepancy above the scatter"]
        lines += ["", "feature errors (z, in units of the measured scatter):"]
        lines += [f"  {k:18s} {z:8.2f}" for k, z in v.feature_z.items()]
        lines += [f"note: {n}" for n in v.notes]
        self.fails_view.setPlainText("\n".join(lines))
        rows = [p for p in v.parameters if p["fitted"]]
        self.params_table.setRowCount(len(rows))
        for r, p in enumerate(rows):
            sig = f" ± {p['sigma']:.3g}" if p["sigma"] is not None else ""
            flag = "" if p["determined"] else "  (not determined by these data)"
            self.params_table.setItem(r, 0, _item(p["name"]))
            self.params_table.setItem(r, 1, _item(f"{p['value']:.5g}{sig}{flag}"))
            self.params_table.setItem(r, 2, _item(p["unit"]))
        change = ""
        if math.isfinite(previous) and previous > 0:
            change = f" ({(v.error - previous) / previous * 100:+.0f} % from {previous:.3g})"
        self._say(f"{v.label}: error {v.error:.3g}{change}")

    def _show_overlay(self, index: int) -> None:
        if self.view is None or not 0 <= index < len(self.view.overlays):
            return
        o = self.view.overlays[index]
        self.meas_curve.setData(o.t_s, o.ft_N)
        self.model_curve.setData(o.t_model_s, o.ft_model_N)
        self.meas_loop.setData(o.delta_m - o.delta_m[0], o.ft_N)
        self.model_loop.setData(o.delta_model_m - o.delta_model_m[0], o.ft_model_N)
        self.time_plot.setTitle(f"{Path(o.name).name}: measured (grey) and {self.view.label} (red)",
                                size="9pt")

    def _show_history(self) -> None:
        for t in self._history_labels:
            self.history_plot.removeItem(t)
        self._history_labels = []
        if not self.history:
            self.history_curve.setData([], [])
            return
        x = np.arange(len(self.history), dtype=float)
        logs = np.log10([max(e, 1e-6) for _, e in self.history])
        self.history_curve.setData(x, logs)
        ticks = [(float(i), self._step_name(i)) for i in range(len(self.history))]
        self.history_plot.getAxis("bottom").setTicks([ticks])
        for xi, (_, e) in zip(x, self.history, strict=True):
            label = pg.TextItem(f"{e:.3g}", color=_MODEL, anchor=(0.5, 1.2))
            label.setPos(float(xi), float(np.log10(max(e, 1e-6))))
            self.history_plot.addItem(label)
            self._history_labels.append(label)
        self.history_plot.setXRange(-0.5, len(self.history) - 0.5)
        self.history_plot.setYRange(min(float(logs.min()), 0.0) - 0.3, float(logs.max()) + 0.4,
                                    padding=0)

    def _step_name(self, i: int) -> str:
        label = self.history[i][0]
        return label if i == 0 else "+ " + label.rsplit(" + ", 1)[-1]

    def _show_residual(self, v: CompareView) -> None:
        t = self.residual_table
        t.clear()
        t.setRowCount(len(v.features))
        t.setColumnCount(len(v.covariates))
        t.setHorizontalHeaderLabels([c.replace(" ", "\n", 1) for c in v.covariates])
        t.setVerticalHeaderLabels([_short(f) for f in v.features])
        for i, phrase in enumerate(v.phrases):
            header = t.verticalHeaderItem(i)
            if header is not None:
                header.setToolTip(phrase)
        zmax = max(1.0, float(np.max(np.abs(v.residual)))) if v.residual.size else 1.0
        for i in range(len(v.features)):
            for j in range(len(v.covariates)):
                z = float(v.residual[i, j])
                item = _item(f"{z:+.1f}" if z else "", f"{v.phrases[i]} vs {v.covariates[j]}: "
                             f"trend amplitude {z:+.2f} z")
                item.setBackground(QBrush(_z_colour(z, zmax)))
                item.setTextAlignment(Qt.AlignmentFlag.AlignCenter)
                t.setItem(i, j, item)
        t.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)

    def _show_plugin_params(self) -> None:
        """The plug-in candidates' parameters: one row each, the effect named on its first."""
        rows = [(cp, i, pv) for cp in self.plugin_params.values()
                for i, pv in enumerate(cp.params)]
        t = self.plugin_table
        t.setRowCount(len(rows))
        for r, (cp, i, pv) in enumerate(rows):
            state = "" if cp.final else "  (fitting: no uncertainty yet)"
            note = f"  {cp.note}" if cp.note and i == 0 else ""
            cells = (cp.effect if i == 0 else "", pv.name, pv.text(),
                     f"{cp.error:.3g}{state}{note}" if i == 0 else "")
            for c, text in enumerate(cells):
                t.setItem(r, c, _item(text, text if c == 3 else ""))
        t.resizeColumnsToContents()
        t.horizontalHeader().setStretchLastSection(True)
        shown = bool(rows)
        self.plugin_label.setVisible(shown)
        t.setVisible(shown)

    def _show_ranking(self, d: DiagnoseView) -> None:
        self.diagnosis = d
        for cp in d.plugin_params:
            self.plugin_params[cp.effect] = cp
        self._show_plugin_params()
        t = self.ranking_table
        t.setRowCount(len(d.rows))
        for r, s in enumerate(d.rows):
            red = f"{s.error_reduction * 100:.0f} %" if math.isfinite(s.error_reduction) else "-"
            dbic = f"{s.delta_bic:.1f}" if math.isfinite(s.delta_bic) else "-"
            cells = (s.effect, f"{s.error:.3g}", red, dbic, "yes" if s.significant else "",
                     s.explains)
            for c, text in enumerate(cells):
                item = _item(text, text if c == 5 else "")
                if s.significant:
                    item.setForeground(QBrush(QColor(_GREEN)))
                t.setItem(r, c, item)
        t.resizeColumnsToContents()
        extra = f" ({', '.join(d.candidates)})" if d.candidates else ""
        text = (f"on {d.label} (error {d.baseline_error:.3g}): verdict <b>{d.verdict}</b>{extra}")
        if d.unexplained:
            text += f"<br>{d.unexplained}"
        if d.suggest:
            text += f"<br>to tell them apart: {d.suggest}"
        self.verdict_label.setText(text)
        self.details.setCurrentIndex(1)
        best = next((s.effect for s in d.rows if s.significant), None)
        if best is not None:
            self._fill_effects()
            self.effect_combo.setCurrentText(best)
        self._say(f"ranking on {d.label}: verdict {d.verdict}" + (
            f"; press Add effect to add {best}" if best else ""))

    def _ranking_selected(self) -> None:
        rows = {i.row() for i in self.ranking_table.selectedItems()}
        if len(rows) == 1:
            cell = self.ranking_table.item(rows.pop(), 0)
            if cell is not None and self.effect_combo.findText(cell.text()) >= 0:
                self.effect_combo.setCurrentText(cell.text())

    def shutdown(self) -> None:
        """Stop a fit still running."""
        self.job.cancel()
