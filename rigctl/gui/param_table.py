"""The protocol parameter editor of the run panel: one row a parameter (name, value, unit,
description), the values as text exactly like the command line's ``--param NAME=VALUE``, and the
rows a refusal names marked in red with the reason in the value's tooltip."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QHeaderView, QTableWidget, QTableWidgetItem, QWidget

from experiments.errors import PlanError
from experiments.params import parse_assignments, resolve
from experiments.protocols import Protocol

COLUMNS = ("name", "value", "unit", "description")
_MARKED = QColor("#ffcdd2")


def format_value(value: float | int | tuple[float, ...]) -> str:
    """A parameter value as the CLI would take it (lists comma-separated; round-trips exactly)."""
    if isinstance(value, tuple):
        return ", ".join(repr(float(v)) for v in value)
    return str(value) if isinstance(value, int) else repr(float(value))


class ParamTable(QTableWidget):
    """The parameters of one protocol (:meth:`show_protocol`); only the value column is editable."""

    edited = Signal()
    """The operator changed a value (the marks of a refusal are cleared first)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(0, len(COLUMNS), parent)
        self._protocol: Protocol | None = None
        self.setHorizontalHeaderLabels(list(COLUMNS))
        header = self.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(1, QHeaderView.ResizeMode.Interactive)
        header.setSectionResizeMode(2, QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        self.setColumnWidth(1, 170)
        self.verticalHeader().setVisible(False)
        self.itemChanged.connect(self._on_item_changed)

    @property
    def protocol(self) -> Protocol:
        if self._protocol is None:
            raise RuntimeError("no protocol shown yet")
        return self._protocol

    def show_protocol(self, p: Protocol) -> None:
        """One row a parameter of ``p``, at its default value."""
        self._protocol = p
        self.blockSignals(True)
        self.setRowCount(len(p.params))
        for row, d in enumerate(p.params):
            cells = (d.name, format_value(d.default), d.unit, d.doc)
            for col, text in enumerate(cells):
                item = QTableWidgetItem(text)
                item.setToolTip(f"{d.name} [{d.unit}]: {d.doc}; default {format_value(d.default)}"
                                + ("; comma-separated list" if d.is_list else ""))
                if col != 1:
                    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                self.setItem(row, col, item)
        self.blockSignals(False)

    def defaults(self) -> dict[str, str]:
        return {d.name: format_value(d.default) for d in self.protocol.params}

    def values(self) -> dict[str, str]:
        """The values as text, by parameter name."""
        out: dict[str, str] = {}
        for row in range(self.rowCount()):
            name, value = self.item(row, 0), self.item(row, 1)
            if name is not None and value is not None:
                out[name.text()] = value.text()
        return out

    def set_value(self, name: str, value: str) -> None:
        row = self._rows().get(name)
        cell = None if row is None else self.item(row, 1)
        if cell is None:
            raise KeyError(f"protocol '{self.protocol.name}' has no parameter '{name}'")
        cell.setText(value)

    def given(self) -> dict[str, str]:
        """The values changed from their defaults, parsed and checked as the CLI's ``--param``.

        Raises PlanError naming the parameter (and marks its row)."""
        p = self.protocol
        defaults = self.defaults()
        items = [f"{k}={v}" for k, v in self.values().items() if v.strip() != defaults[k]]
        given = parse_assignments(items)
        try:
            resolve(p.params, given, p.name)
        except PlanError as exc:
            self.mark_bad((), str(exc))
            raise
        return given

    def marked(self) -> list[str]:
        """The parameters whose row is marked as the cause of a refusal or a bad value."""
        return [name for name, row in self._rows().items()
                if (cell := self.item(row, 1)) is not None
                and cell.data(Qt.ItemDataRole.UserRole) is not None]

    def mark_bad(self, names: tuple[str, ...], message: str) -> None:
        """Mark in red the rows of ``names`` and of every parameter the message names; the cause
        is in the value cell's tooltip (the normal tooltip comes back with the next edit)."""
        self.blockSignals(True)
        for name, row in self._rows().items():
            if name not in names and f"'{name}'" not in message:
                continue
            for col in range(self.columnCount()):
                cell = self.item(row, col)
                if cell is None:
                    continue
                cell.setBackground(_MARKED)
                if col == 1:
                    cell.setData(Qt.ItemDataRole.UserRole, cell.toolTip())
                    cell.setToolTip(f"this value causes the refusal: {message}")
        self.blockSignals(False)

    def clear_marks(self) -> None:
        self.blockSignals(True)
        for row in range(self.rowCount()):
            for col in range(self.columnCount()):
                cell = self.item(row, col)
                if cell is None:
                    continue
                cell.setBackground(QColor(0, 0, 0, 0))
                saved = cell.data(Qt.ItemDataRole.UserRole)
                if col == 1 and saved is not None:
                    cell.setToolTip(str(saved))
                    cell.setData(Qt.ItemDataRole.UserRole, None)
        self.blockSignals(False)

    def _rows(self) -> dict[str, int]:
        rows: dict[str, int] = {}
        for row in range(self.rowCount()):
            item = self.item(row, 0)
            if item is not None:
                rows[item.text()] = row
        return rows

    def _on_item_changed(self, item: QTableWidgetItem) -> None:
        if item.column() != 1:
            return
        self.clear_marks()
        self.edited.emit()
