"""The operator's run panel: choose a protocol, set its parameters, dry-run it, run it, watch it.

Where the jobs execute is a :class:`~rigctl.gui.run_backend.RunBackend`, the only thing the panel
knows of it: the run service (:class:`~rigctl.gui.service_backend.ServiceBackend`, ``rigctl gui``)
or a worker thread of this process (:class:`~rigctl.gui.inprocess_backend.InProcessBackend`,
``--in-process`` and a panel given an open rig). The GUI thread never waits on a device. The
back-end answers with Qt signals queued into the GUI thread (the plan, progress, live data, the
outcome); the panel calls it from the GUI thread (start, pause, resume, abort, e-stop). Live forces
come from a bounded mailbox drained by a QTimer in the GUI thread: a slow GUI loses its own oldest
blocks (counted), never the recorder's.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QCloseEvent, QFont
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from experiments.errors import PlanError
from experiments.protocols import PROTOCOLS, Protocol
from experiments.runner import Plan, RunOutcome
from rigctl.config import RigConfig
from rigctl.gui.live_plot import LivePlot
from rigctl.gui.param_table import ParamTable
from rigctl.gui.queue_view import QueueView
from rigctl.gui.run_backend import BackendSignals, JobResult, LiveBlocks, RunBackend, RunJob
from rigctl.gui.run_summary import values_summary
from rigctl.rigs import OpenRig, parse_speed
from rigctl.runservice.queue import QueueState
from rigctl.runservice.wire import Address, JobSpec
from rigctl.status import RunStatus

PLOT_WINDOW_S = 60.0
"""Rig time shown by the live plot."""
DRAIN_INTERVAL_MS = 33
"""The live mailboxes are drained and the plot redrawn this often (about 30 frames per second)."""
ABORT_REASON = "aborted by the operator"
ESTOP_REASON = "emergency stop by the operator"

_RED, _GREEN, _ORANGE = "#c62828", "#2e7d32", "#e65100"


def make_backend(signals: BackendSignals, config: RigConfig, backend: str, *,
                 rig: OpenRig | None, speed: str, service: Address | None,
                 config_path: str | None) -> RunBackend:
    """The run service's client if ``service`` is given (and no rig), else a worker thread."""
    if service is not None and rig is None:
        from rigctl.gui.service_backend import ServiceBackend
        from rigctl.runservice.client import ServiceClient

        return ServiceBackend(signals, lambda on_message: ServiceClient.ensure(
            on_message, backend=backend, speed_text=speed, config_path=config_path,
            address=service))
    from rigctl.gui.inprocess_backend import InProcessBackend

    return InProcessBackend(signals, config, backend, rig)


class RunPanel(QWidget):
    """Protocol, parameters, output, speed; dry run / start / pause / resume / abort; live view."""

    status_message = Signal(str)
    """Each status line the panel shows (the main window's status bar repeats it)."""

    def __init__(
        self,
        config: RigConfig,
        backend: str = "sim",
        *,
        rig: OpenRig | None = None,
        speed: str = "1",
        service: Address | None = None,
        config_path: str | None = None,
        parent: QWidget | None = None,
    ) -> None:
        """``rig``: an already open rig used for every action (tests, embedding). ``service``: run in
        the run service listening there (started if none is; ``rigctl gui`` does this), so a run
        outlives the window. Otherwise the panel opens ``backend`` with ``config`` in a worker thread
        for each dry run or run and closes it afterwards."""
        super().__init__(parent)
        self.config = config
        self.backend = backend
        self._given_rig = rig
        self.last_outcome: RunOutcome | None = None
        self._close_when_done = False
        self._unaborted_job = False
        """A job has begun and the operator has not aborted it (nor pressed the e-stop during it):
        closing the window while it goes asks first."""
        self._sub: LiveBlocks | None = None
        self._plan: Plan | None = None
        self._progress: tuple[int, int, str, float, float, float] | None = None
        self._t_latest = math.nan
        self._wall_start = 0.0
        self._speed = 1.0
        self._pause_rig_t0 = math.nan
        """Rig time (latest received) when the current pause began; NaN when not paused."""
        self._pause_wall_t0 = math.nan
        self._step_paused_rig_s = 0.0
        """Rig time spent paused since the current step began (not progress)."""
        self._paused_rig_s = 0.0
        self._paused_wall_s = 0.0
        """Rig and wall time spent paused in this run (left out of the rig-time/wall-time rate)."""
        self._refusal_shown = False
        self._running_protocol = ""
        self._queue_item: int | None = None
        """The queue item of the run going (None: a run started on its own)."""
        self._file_shown = False
        self._job_serial = 0
        """The serial of the latest job begun (RunBackend.new_job)."""
        self.run_path: Path | None = None
        """The run file of the latest run (None before one and for a dry run)."""
        self._sig = BackendSignals(self)
        self._sig.planned.connect(self._on_planned)
        self._sig.subscribed.connect(self._on_subscribed)
        self._sig.progress.connect(self._on_progress)
        self._sig.done.connect(self._on_done)
        self._sig.service_log.connect(self._on_service_log)
        self._sig.service_lost.connect(self._on_service_lost)
        self._sig.remote_started.connect(self._on_remote_started)
        self._sig.queue_state.connect(self._on_queue_state)
        self._build(speed)
        self._timer = QTimer(self)
        self._timer.setInterval(DRAIN_INTERVAL_MS)
        self._timer.timeout.connect(self._tick)
        self.queue_view.command.connect(self._on_queue_command)
        self.queue_view.add_requested.connect(self.add_to_queue)
        self._runs: RunBackend = make_backend(self._sig, config, backend, rig=rig, speed=speed,
                                              service=service, config_path=config_path)
        """Where the jobs execute: the panel talks to it only through the RunBackend protocol."""
        if not self._runs.has_service:
            self.queue_view.setEnabled(False)
            self.queue_view.setToolTip("the queue lives in the run service; this window runs "
                                       "protocols in process (--in-process or a held rig)")
        self._set_state("idle")
        self._fill_params()

    # ------------------------------------------------------------------ layout
    def _build(self, speed: str) -> None:
        self.setWindowTitle(f"rigctl run panel: {self.config.rig.name} ({self.backend})")
        self.protocol_combo = QComboBox()
        for name, p in PROTOCOLS.items():
            self.protocol_combo.addItem(name, name)
            self.protocol_combo.setItemData(self.protocol_combo.count() - 1, p.summary,
                                            Qt.ItemDataRole.ToolTipRole)
        self.protocol_combo.currentIndexChanged.connect(self._fill_params)
        self.summary_label = QLabel()
        self.summary_label.setWordWrap(True)

        self.param_table = ParamTable()
        self.param_table.edited.connect(self._on_value_edited)

        self.out_edit = QLineEdit()
        self.out_edit.setPlaceholderText(
            f"default: {self.config.storage.directory}/<protocol>_<date-time>.h5")
        browse = QPushButton("…")
        browse.setToolTip("choose the run file")
        browse.clicked.connect(self._browse)
        out_row = QHBoxLayout()
        out_row.addWidget(self.out_edit)
        out_row.addWidget(browse)
        self.speed_combo = QComboBox()
        self.speed_combo.setEditable(True)
        self.speed_combo.addItems(["1", "10", "100", "max"])
        self.speed_combo.setCurrentText(speed)
        self.speed_combo.setToolTip("simulated rig clock: 1 (real time), N times faster, or max "
                                    "(paced by the recorder)")
        if self._given_rig is not None:
            self.speed_combo.setCurrentText(self._given_rig.speed_text)
            self.speed_combo.setEnabled(False)
        elif self.backend == "real":
            self.speed_combo.setCurrentText("1")
            self.speed_combo.setEnabled(False)
        self.camera_check = QCheckBox("record camera frames")
        self.camera_check.setChecked(True)
        self.operator_edit = QLineEdit(self.config.rig.operator)
        self.operator_edit.setToolTip("stored in the run file's metadata (as rigctl run --operator)")
        self.notes_edit = QLineEdit()
        self.notes_edit.setPlaceholderText("free text stored with the run (as rigctl run --notes)")

        form = QFormLayout()
        form.addRow("Protocol", self.protocol_combo)
        form.addRow("", self.summary_label)
        form.addRow("Run file", out_row)
        form.addRow("Speed", self.speed_combo)
        form.addRow("", self.camera_check)
        form.addRow("Operator", self.operator_edit)
        form.addRow("Notes", self.notes_edit)

        self.dry_button = QPushButton("Dry run")
        self.dry_button.setToolTip("check the plan against the rig's limits; nothing moves")
        self.start_button = QPushButton("Start")
        self.pause_button = QPushButton("Pause")
        self.resume_button = QPushButton("Resume")
        self.abort_button = QPushButton("Abort")
        self.abort_button.setToolTip("stop, release the normal load, close the file as aborted")
        self.abort_button.setStyleSheet(f"QPushButton:enabled {{ font-weight: bold; color: {_RED} }}")
        self.dry_button.clicked.connect(lambda: self._launch(dry=True))
        self.start_button.clicked.connect(lambda: self._launch(dry=False))
        self.pause_button.clicked.connect(self.pause)
        self.resume_button.clicked.connect(self.resume)
        self.abort_button.clicked.connect(lambda: self.abort())  # not clicked(bool) as reason
        buttons = QHBoxLayout()
        for b in (self.dry_button, self.start_button, self.pause_button, self.resume_button,
                  self.abort_button):
            buttons.addWidget(b)

        self.progress_bar = QProgressBar()
        self.progress_bar.setRange(0, 1000)
        self.progress_bar.setFormat("%p %")
        self.progress_label = QLabel("")
        self.file_label = QLabel("")
        self.file_label.setWordWrap(True)
        self.file_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_label = QLabel("ready")
        self.status_label.setWordWrap(True)
        self.status_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.plan_view = QPlainTextEdit()
        self.plan_view.setReadOnly(True)
        mono = QFont("monospace")
        mono.setStyleHint(QFont.StyleHint.Monospace)
        mono.setPointSize(8)
        self.plan_view.setFont(mono)
        self.plan_view.setPlaceholderText("Dry run: the plan (steps and rig time) appears here")

        self.live = LivePlot(rate_hz=self.config.daq.sample_rate_hz, window_s=PLOT_WINDOW_S,
                             phase_plot=False)
        self.live.setMinimumHeight(260)
        self.ft_curve = self.live.ft_curve
        self.fn_curve = self.live.fn_curve

        left = QVBoxLayout()
        left.addLayout(form)
        left.addWidget(self.param_table, 3)
        left.addLayout(buttons)
        left.addWidget(self.progress_bar)
        left.addWidget(self.progress_label)
        left.addWidget(self.file_label)
        left.addWidget(self.status_label)
        self.queue_view = QueueView()
        right = QVBoxLayout()
        right.addWidget(self.live, 3)
        right.addWidget(self.plan_view, 2)
        right.addWidget(self.queue_view, 2)
        top = QHBoxLayout(self)
        top.addLayout(left, 1)
        top.addLayout(right, 1)
        self.resize(1150, 640)

    # ------------------------------------------------------------------ parameters
    @property
    def protocol(self) -> Protocol:
        return PROTOCOLS[str(self.protocol_combo.currentData())]

    def _fill_params(self) -> None:
        self.param_table.show_protocol(self.protocol)
        self._update_summary()
        self._clear_stale()

    def _update_summary(self) -> None:
        self.summary_label.setText(values_summary(self.protocol, self.param_table.values(),
                                                  self.param_table.defaults()))

    def _on_value_edited(self) -> None:
        self._update_summary()
        self._clear_stale()

    def _clear_stale(self) -> None:
        """A refusal shown for other values (or another protocol) is no longer true: clear it."""
        if not self._refusal_shown or self.busy:
            return
        self._refusal_shown = False
        self.plan_view.clear()
        self.plan_view.setStyleSheet("")
        self._status("values changed: dry run again to check them", None, announce=False)

    def param_values(self) -> dict[str, str]:
        """The table's values as text, by parameter name."""
        return self.param_table.values()

    def set_param(self, name: str, value: str) -> None:
        self.param_table.set_value(name, value)

    def _given(self) -> dict[str, str]:
        """Parameters changed from their defaults, parsed and checked as the CLI's ``--param``.

        Raises PlanError naming the parameter (and marks its row)."""
        return self.param_table.given()

    def marked_params(self) -> list[str]:
        """The parameters whose row is marked as the cause of a refusal or a bad value."""
        return self.param_table.marked()

    def _browse(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Run file", self.out_edit.text()
                                              or str(self.config.storage.directory),
                                              "HDF5 run files (*.h5)")
        if path:
            self.out_edit.setText(path)

    # ------------------------------------------------------------------ actions (GUI thread)
    @property
    def busy(self) -> bool:
        return self._runs.busy

    # ------------------------------------------------------------------ run service messages
    def _on_service_log(self, level: str, text: str) -> None:
        self._sig.run_event.emit(level, text)
        if level in ("warning", "error"):
            self._status(f"run service: {text}", _RED if level == "error" else _ORANGE,
                         announce=False)

    def _on_service_lost(self) -> None:
        self._runs.ended()
        self._timer.stop()
        self._set_state("idle")
        self._status("the run service went away; restart the window to reconnect", _RED)

    def _default_out(self, taken: set[str]) -> Path:
        """``<storage>/<protocol>_<date-time>.h5``, with ``_2``, ``_3``... if taken or existing."""
        folder = Path(self.config.storage.directory)
        folder.mkdir(parents=True, exist_ok=True)
        stem = f"{self.protocol.name}_{time.strftime('%Y%m%d-%H%M%S')}"
        out, n = folder / f"{stem}.h5", 1
        while str(out) in taken or out.exists():
            n += 1
            out = folder / f"{stem}_{n}.h5"
        return out

    def _form_out(self, taken: set[str]) -> tuple[Path, bool] | None:
        """The run file of the form (asking before overwriting) and whether to overwrite; None if
        not to start (the status says why)."""
        text = self.out_edit.text().strip()
        if text:
            out = Path(text).expanduser()
            if str(out) in taken:
                self._status(f"not queued: {out} is already the run file of a queued run", _ORANGE)
                return None
        else:
            try:
                out = self._default_out(taken)
            except OSError as exc:
                self._status(f"storage folder {self.config.storage.directory}: {exc}", _RED)
                return None
        if out.exists():
            if not self._ask(f"{out} exists. Overwrite it?"):
                self._status("not started: the run file exists", _ORANGE)
                return None
            return out, True
        return out, False

    def _begin(self, protocol_name: str, out: Path | None, dry: bool, speed: float,
               queue_item: int | None) -> None:
        """Reset what the panel shows for a new dry run or run (started here or by the queue: a
        queued run's live mailboxes were reset as its ``started`` came)."""
        self._unaborted_job = True
        self.run_path = out
        if queue_item is None:
            self._job_serial = self._runs.new_job()
        self._speed = speed
        self._plan = None
        self._progress = None
        self._pause_rig_t0 = self._pause_wall_t0 = math.nan
        self._step_paused_rig_s = self._paused_rig_s = self._paused_wall_s = 0.0
        self.last_outcome = None
        self._running_protocol = protocol_name
        self._queue_item = queue_item
        self._file_shown = False
        self._refusal_shown = False
        self.param_table.clear_marks()
        self.file_label.setText("")
        self.progress_label.setText("")
        if not dry:
            self._reset_plot()
            self._sig.run_started.emit(out)
            self.progress_bar.setValue(0)
            self.progress_label.setText("starting…")
            self.file_label.setText(f"run file (not yet created): {out}")
            self.file_label.setStyleSheet("color: gray")
        self.plan_view.setStyleSheet("")
        item = f"queue item {queue_item}: " if queue_item is not None else ""
        self._status("dry run: checking the plan against the limits…" if dry
                     else f"{item}starting {protocol_name}…", None)
        self._set_state("busy" if dry else "running")

    def _launch(self, dry: bool) -> None:
        if self.busy:
            return
        try:
            given = self._given()
            speed_text = self.speed_combo.currentText().strip()
            speed = parse_speed(speed_text)
        except (PlanError, ValueError) as exc:
            self._status(str(exc), _RED)
            return
        out = None
        overwrite = False
        if not dry:
            chosen = self._form_out(set())
            if chosen is None:
                return
            out, overwrite = chosen
        operator, notes = self.operator_edit.text().strip(), self.notes_edit.text().strip()
        self._begin(self.protocol.name, out, dry, speed, None)
        job = RunJob(dry, self.protocol, given, speed, speed_text, out, overwrite,
                     self.camera_check.isChecked(), operator, notes, self._job_serial)
        if not self._runs.start(job):
            self._on_service_lost()

    # ------------------------------------------------------------------ the queue (run service)
    def add_to_queue(self) -> bool:
        """Queue the form's protocol, values, run file, operator and notes; False if refused."""
        if not self._runs.has_service:
            self._status("the queue needs the run service (not with --in-process)", _RED)
            return False
        try:
            given = self._given()
            speed_text = self.speed_combo.currentText().strip()
            speed = parse_speed(speed_text)
        except (PlanError, ValueError) as exc:
            self._status(str(exc), _RED)
            return False
        taken = {str(it.spec.out) for it in self.queue_view.state.items
                 if it.status in ("pending", "running")}
        chosen = self._form_out(taken)
        if chosen is None:
            return False
        out, overwrite = chosen
        job = RunJob(False, self.protocol, given, speed, speed_text, out, overwrite,
                     self.camera_check.isChecked(), self.operator_edit.text().strip(),
                     self.notes_edit.text().strip())
        if not self._runs.enqueue(job):
            self._on_service_lost()
            return False
        self._status(f"queued {self.protocol.name} -> {out}", None, announce=False)
        return True

    def _on_queue_command(self, kind: str, payload: Any) -> None:
        if kind == "queue_abort" and not self._ask(
                "Abort the queue? The current run is aborted (safe state) and the pending runs "
                "are dropped."):
            return
        if not self.send_service(kind, payload):
            self._status("the run service is gone: the queue cannot be changed", _RED)

    def _on_queue_state(self, state: QueueState) -> None:
        self.queue_view.show_state(state)
        self._set_state(self.state)

    def _on_remote_started(self, spec: JobSpec) -> None:
        """The service started a run that this window did not launch: a queued one."""
        if spec.queue_item is None:
            return
        self._runs.adopt()
        self._begin(spec.protocol, None if spec.out is None else Path(spec.out), spec.dry,
                    parse_speed(spec.speed_text), spec.queue_item)

    def pause(self) -> None:
        if self.busy:
            if not math.isfinite(self._pause_wall_t0):  # not paused already
                self._pause_rig_t0 = self._t_latest
                self._pause_wall_t0 = time.monotonic()
            self._runs.pause()
            self._set_state("paused")
            self._status("paused: the stages hold where they are (rig time and recording go on)",
                         _ORANGE)

    def resume(self) -> None:
        if self.busy:
            self._end_pause()
            self._runs.resume()
            self._set_state("running")
            self._status("running", None)

    def _end_pause(self) -> None:
        """Count the pause just ended as paused time (progress and ETA leave it out)."""
        if math.isfinite(self._pause_wall_t0):
            self._paused_wall_s += time.monotonic() - self._pause_wall_t0
        if math.isfinite(self._pause_rig_t0) and math.isfinite(self._t_latest):
            held = max(self._t_latest - self._pause_rig_t0, 0.0)
            self._step_paused_rig_s += held
            self._paused_rig_s += held
        self._pause_rig_t0 = self._pause_wall_t0 = math.nan

    def abort(self, reason: str = ABORT_REASON) -> None:
        if self.busy:
            self._end_pause()
            self._unaborted_job = False
            self._runs.abort(reason)
            self._set_state("aborting")
            self._status("aborting: stopping and releasing the normal load…", _ORANGE)

    def emergency_stop(self, reason: str = ESTOP_REASON) -> str:
        """The drivers' latched emergency stop on both stages, from any state; aborts a run.

        Returns what was done (for the status bar). The back-end sets the run's abort before the
        stages are stopped (in the run service the service does the same), so that the protocol's
        step sees an abort (status ``aborted``) rather than only the stage alarm the e-stop causes.
        """
        running = self.busy
        if running:
            self._unaborted_job = False
        text = self._runs.emergency_stop(reason)
        if running:
            self._set_state("aborting")
        self._status(text, _RED)
        return text

    def shutdown(self, timeout_s: float = 30.0) -> bool:
        """Abort any run and wait for the worker (safe state reached); True if it ended."""
        self.abort()
        self._runs.wait(timeout_s)
        return not self.busy

    @property
    def signals(self) -> BackendSignals:
        """The panel's signals (the main window connects ``devices`` and ``jog_result``)."""
        return self._sig

    @property
    def has_service(self) -> bool:
        return self._runs.has_service

    def send_service(self, kind: str, payload: Any = None) -> bool:
        """A command to the run service (False without one, or if it is gone)."""
        return self._runs.send(kind, payload)

    def disconnect_service(self) -> None:
        """Close the connection to the run service (it stops by itself once idle with no client)."""
        self._runs.close()

    def _ask(self, question: str) -> bool:
        answer = QMessageBox.question(self, "rigctl", question,
                                      QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                                      QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes

    def closeEvent(self, event: QCloseEvent) -> None:
        if not self.busy:
            self._timer.stop()
            event.accept()
            return
        if not self._close_when_done:
            if self._unaborted_job and not self._ask(
                    "A run is in progress. Abort it (the rig is brought to a safe state) and close?"):
                event.ignore()
                return
            self._close_when_done = True
            self.abort(ABORT_REASON + " (window closed)")
            self._status("closing once the rig is in a safe state…", _ORANGE)
        event.ignore()  # closed by _on_done when the worker has finished

    def _set_state(self, state: str) -> None:
        idle = state == "idle"
        queue_running = self.queue_view.state.running
        self.dry_button.setEnabled(idle and not queue_running)
        self.start_button.setEnabled(idle and not queue_running)
        self.queue_view.set_busy(not idle and self._queue_item is None)
        self.protocol_combo.setEnabled(idle)
        self.param_table.setEnabled(idle)
        self.out_edit.setEnabled(idle)
        self.camera_check.setEnabled(idle)
        self.speed_combo.setEnabled(idle and self._given_rig is None and self.backend != "real")
        self.pause_button.setEnabled(state == "running")
        self.resume_button.setEnabled(state == "paused")
        self.abort_button.setEnabled(state in ("running", "paused"))
        self.state = state

    def _status(self, text: str, color: str | None, *, announce: bool = True) -> None:
        if announce:
            self._sig.run_event.emit("error" if color == _RED else "warning" if color == _ORANGE
                                 else "info", text)
        self.status_label.setText(text)
        self.status_label.setStyleSheet(f"color: {color}; font-weight: bold" if color else "")
        self.status_message.emit(text)

    # ------------------------------------------------------------------ signal handlers (GUI thread)
    def _on_planned(self, plan: Plan) -> None:
        self._plan = plan
        text = plan.summary()
        if math.isfinite(self._speed):
            text += f"\nwall time at speed {self._speed:g}: ~{plan.duration_s / self._speed:.0f} s"
        self.plan_view.setPlainText(text)

    def _on_subscribed(self, sub: LiveBlocks) -> None:
        self._sub = sub
        self._wall_start = time.monotonic()
        self._timer.start()
        if self.state == "running":
            item = f"queue item {self._queue_item}: " if self._queue_item is not None else ""
            self._status(f"{item}running {self._running_protocol}: recording", None)
        self._show_file()

    def _show_file(self) -> None:
        """The run file's name once it exists (checked until it does: it is created before the
        acquisition starts, so by the first live data at the latest)."""
        if self._file_shown or self.run_path is None or not self.run_path.exists():
            return
        self._file_shown = True
        self.file_label.setText(f"run file: {self.run_path}")
        self.file_label.setStyleSheet("")

    def _on_progress(self, i: int, n: int, desc: str, elapsed: float, eta: float,
                     t_dev: float) -> None:
        self._progress = (i, n, desc, elapsed, eta, t_dev)
        self._step_paused_rig_s = 0.0
        if math.isfinite(self._pause_rig_t0) and math.isfinite(t_dev):
            # a step began during a pause (its hold ended): the pause counts from the step's start
            self._paused_rig_s += max(t_dev - self._pause_rig_t0, 0.0)
            self._pause_rig_t0 = max(self._pause_rig_t0, t_dev)
        self._show_progress()

    def _on_done(self, result: JobResult) -> None:
        self._runs.ended()
        self._tick()
        self._timer.stop()
        self._sub = None
        self._end_pause()
        queued = self._queue_item is not None
        self._queue_item = None
        self._set_state("idle")
        self._show_file()
        if result.kind != "run":
            self.progress_label.setText("")  # no "starting…" left over
            self.progress_bar.setValue(0)
            if not self._file_shown:
                self.file_label.setText("")
        if result.kind == "dry":
            self._status("dry run: plan within the limits; nothing moved", _GREEN)
        elif result.kind == "refused":
            self.plan_view.setPlainText(result.message)
            self.plan_view.setStyleSheet(f"color: {_RED}")
            self._status(result.message, _RED)
            if not queued:  # a queued run's values are not those of the form
                self.param_table.mark_bad(result.culprits, result.message)
                self._refusal_shown = True
        elif result.kind == "error":
            self.plan_view.setStyleSheet(f"color: {_RED}")
            self._status(f"not run: {result.message}", _RED)
        else:
            self._show_outcome(result.outcome)
        if self._close_when_done:
            QTimer.singleShot(0, self.window().close)  # the main window when embedded

    def _show_outcome(self, outcome: RunOutcome | None) -> None:
        if outcome is None:
            return
        self.last_outcome = outcome
        text = f"{outcome.status}: {outcome.path} ({outcome.wall_s:.1f} s wall)"
        st = outcome.stats
        if st is not None:
            text += (f"; {st.daq_samples} samples, "
                     f"{st.daq_dropped + st.queue_dropped_samples} dropped")
        if outcome.error:
            text += f"\n{outcome.error}"
        if outcome.status == RunStatus.COMPLETED:
            self.progress_bar.setValue(self.progress_bar.maximum())
            self.progress_label.setText("completed")
            self._status(text, _GREEN)
        else:
            self.progress_label.setText(f"{outcome.status}: the rig is in a safe state"
                                        if not outcome.problems else
                                        f"{outcome.status}: safe state INCOMPLETE")
            self._status(text, _ORANGE if outcome.status == RunStatus.ABORTED else _RED)

    # ------------------------------------------------------------------ live data (GUI thread)
    def _reset_plot(self) -> None:
        self.live.clear()
        self.live.force_plot.setTitle(None)
        self._t_latest = math.nan

    @property
    def samples_received(self) -> int:
        return self.live.samples

    def _tick(self) -> None:
        sub = self._sub
        if sub is None:
            return
        self._show_file()
        blocks = sub.drain()
        frames = self._runs.drain_frames()
        if frames:
            self._sig.live_frames.emit(frames)
        if blocks:
            self._sig.live_blocks.emit(blocks)
            self.live.feed(blocks)
            self._t_latest = float(blocks[-1]["t_s"][-1])
            self.live.redraw()
            if sub.dropped:
                self.live.force_plot.setTitle(
                    f"live view skipped {sub.dropped} blocks (display only)", color=_ORANGE, size="8pt")
        self._show_progress()

    def _show_progress(self) -> None:
        """Progress and ETA from the plan: the steps done plus the rig time spent in the current
        step (capped at its estimate). Paused rig time is left out, and while paused the numbers
        stand still at the moment of the pause (the rig's clock and the recording go on)."""
        plan, prog = self._plan, self._progress
        if plan is None or prog is None:
            return
        i, n, desc, elapsed, eta, t_dev = prog
        paused = math.isfinite(self._pause_rig_t0) or math.isfinite(self._pause_wall_t0)
        t_now = self._pause_rig_t0 if paused else self._t_latest
        wall_now = self._pause_wall_t0 if math.isfinite(self._pause_wall_t0) else time.monotonic()
        total = max(plan.duration_s, 1e-9)
        step_est = plan.steps[i - 1].estimate_s if 0 < i <= len(plan.steps) else 0.0
        since_step = 0.0
        if math.isfinite(t_now) and math.isfinite(t_dev):
            since_step = max(t_now - t_dev, 0.0)
        in_step = min(max(since_step - self._step_paused_rig_s, 0.0), step_est)
        done = min(total - eta + in_step, total)
        remaining = max(eta - in_step, 0.0)
        self.progress_bar.setValue(round(1000 * done / total))
        rig_elapsed = elapsed + since_step
        wall = wall_now - self._wall_start - self._paused_wall_s
        active_rig = rig_elapsed - self._paused_rig_s
        rate = active_rig / wall if wall > 1.0 and active_rig > 0 else (
            self._speed if math.isfinite(self._speed) else math.nan)
        wall_eta = ""
        if rate == rate and rate > 0:
            wall_s = remaining / rate
            wall_eta = f" (~{wall_s:.0f} s wall)" if wall_s >= 1 else " (<1 s wall)"
        note = " [paused: progress and ETA held]" if paused else ""
        self.progress_label.setText(
            f"step {i}/{n}: {desc}{note}\nrig time {rig_elapsed:.0f} s of ~{total:.0f} s, "
            f"ETA {remaining:.0f} s{wall_eta}")


def panel_state(panel: RunPanel) -> dict[str, Any]:
    """What the panel shows, for logs and tests."""
    return {"state": panel.state, "status": panel.status_label.text(),
            "progress": panel.progress_bar.value(), "samples": panel.samples_received}
