"""The Protocols tab's queue: the queued runs with their status, and the buttons that edit and run it.

The queue itself lives in the run service (:mod:`rigctl.runservice.queue`); this widget only shows
the :class:`~rigctl.runservice.queue.QueueState` the service sends and asks for changes through the
``command`` signal ``(kind, payload)``, which the run panel forwards to the service.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QAbstractItemView,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from rigctl.runservice.queue import COMPLETED, DROPPED, PENDING, RUNNING, QueueState

QUEUE_ABORT_REASON = "queue aborted by the operator"
_COLUMNS = ("#", "protocol", "changed parameters", "run file", "status")
_STATUS_COLORS = {COMPLETED: "#2e7d32", RUNNING: "#1565c0", PENDING: "#424242", DROPPED: "#757575",
                  "aborted": "#e65100"}
_FAILED_COLOR = "#c62828"


class QueueView(QWidget):
    """Queued runs (number, protocol, changed parameters, run file, status) and the queue's buttons."""

    command = Signal(str, object)
    """(kind, payload): ``queue_remove``/``queue_move``/``queue_start``/``queue_abort``/``queue_clear``."""
    add_requested = Signal()
    """The operator asks to queue the protocol and values of the form above."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.state = QueueState()
        self.add_button = QPushButton("Add to queue")
        self.add_button.setToolTip("queue the protocol with the values, run file, operator and "
                                   "notes above")
        self.remove_button = QPushButton("Remove")
        self.up_button = QPushButton("▲")
        self.up_button.setToolTip("move the chosen pending run up")
        self.down_button = QPushButton("▼")
        self.down_button.setToolTip("move the chosen pending run down")
        self.start_button = QPushButton("Start queue")
        self.start_button.setToolTip("run the pending runs in order; a run that does not complete "
                                     "stops the queue (Pause/Resume above hold the current run)")
        self.abort_button = QPushButton("Abort queue")
        self.abort_button.setToolTip("abort the current run (safe state, file 'aborted') and drop "
                                     "the pending runs")
        self.abort_button.setStyleSheet("QPushButton:enabled { font-weight: bold; color: #c62828 }")
        self.clear_button = QPushButton("Clear ended")
        self.clear_button.setToolTip("remove the runs that have ended from the list")
        self.table = QTableWidget(0, len(_COLUMNS))
        self.table.setHorizontalHeaderLabels(list(_COLUMNS))
        self.table.verticalHeader().setVisible(False)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        header = self.table.horizontalHeader()
        for col in (0, 1, 4):
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(2, QHeaderView.ResizeMode.Stretch)
        header.setSectionResizeMode(3, QHeaderView.ResizeMode.Stretch)
        self.message_label = QLabel("")
        self.message_label.setWordWrap(True)
        self.message_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)

        self.add_button.clicked.connect(self.add_requested.emit)
        self.remove_button.clicked.connect(lambda: self._on_selected("queue_remove"))
        self.up_button.clicked.connect(lambda: self._on_selected("queue_move", -1))
        self.down_button.clicked.connect(lambda: self._on_selected("queue_move", +1))
        self.start_button.clicked.connect(lambda: self.command.emit("queue_start", None))
        self.abort_button.clicked.connect(
            lambda: self.command.emit("queue_abort", QUEUE_ABORT_REASON))
        self.clear_button.clicked.connect(lambda: self.command.emit("queue_clear", None))
        self.table.itemSelectionChanged.connect(self._enable)

        row = QHBoxLayout()
        for b in (self.add_button, self.remove_button, self.up_button, self.down_button,
                  self.start_button, self.abort_button, self.clear_button):
            row.addWidget(b)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        title = QLabel("<b>Queue</b>: runs in sequence, each with its own values and run file")
        layout.addWidget(title)
        layout.addLayout(row)
        layout.addWidget(self.table)
        layout.addWidget(self.message_label)
        self.busy = False
        self._enable()

    def selected_item(self) -> int | None:
        rows = self.table.selectionModel().selectedRows()
        if not rows:
            return None
        cell = self.table.item(rows[0].row(), 0)
        return int(cell.text()) if cell is not None else None

    def _on_selected(self, kind: str, delta: int | None = None) -> None:
        item = self.selected_item()
        if item is not None:
            self.command.emit(kind, item if delta is None else (item, delta))

    def set_busy(self, busy: bool) -> None:
        """A run started outside the queue is going (the queue cannot start)."""
        self.busy = busy
        self._enable()

    def show_state(self, state: QueueState) -> None:
        chosen = self.selected_item()
        self.state = state
        table = self.table
        table.setRowCount(len(state.items))
        for row, it in enumerate(state.items):
            given = ", ".join(f"{k}={v}" for k, v in it.spec.given.items()) or "(defaults)"
            status = it.status + (f": {it.message}" if it.message else "")
            cells = (str(it.item), it.spec.protocol, given, str(it.spec.out), status)
            for col, text in enumerate(cells):
                cell = QTableWidgetItem(text)
                cell.setToolTip(text)
                if col == 4:
                    cell.setForeground(QColor(_STATUS_COLORS.get(it.status, _FAILED_COLOR)))
                table.setItem(row, col, cell)
            if it.item == chosen:
                table.selectRow(row)
        self.message_label.setText(state.message)
        self._enable()

    def _enable(self) -> None:
        st = self.state
        chosen = self.selected_item()
        pending = [it for it in st.items if it.status == PENDING]
        chosen_pending = any(it.item == chosen for it in pending)
        self.remove_button.setEnabled(chosen is not None and any(
            it.item == chosen and it.status != RUNNING for it in st.items))
        self.up_button.setEnabled(chosen_pending)
        self.down_button.setEnabled(chosen_pending)
        self.start_button.setEnabled(bool(pending) and not st.running and not self.busy)
        self.abort_button.setEnabled(st.running)
        self.clear_button.setEnabled(any(it.status not in (PENDING, RUNNING) for it in st.items))
