"""The Devices tab: each stage's position, limits and status, live readings, jog, e-stop state.

The panel only shows :class:`~rigctl.runservice.devices.RigSnapshot` objects handed to
:meth:`DevicesPanel.show_snapshot` and calls the ``jog`` / ``reset_estop`` functions it is given: the
window wires them to the run service (which owns the rig) or to a rig it holds itself. A jog beyond a
limit is refused by the stage's driver before anything moves; the refusal's text is shown in red.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from rigctl.runservice.devices import AXES, RigSnapshot

JogFn = Callable[[str, float, float], object]
"""jog(axis, delta_m, velocity_m_s)"""

_RED, _GREEN, _ORANGE = "#c62828", "#2e7d32", "#e65100"
_READINGS = (("ft_N", "Ft", "N", 1.0), ("fn_N", "Fn", "N", 1.0), ("delta_m", "delta", "um", 1e6),
             ("d1_m", "d1", "um", 1e6),
             ("d2_m", "d2", "um", 1e6), ("x_stage_m", "x stage", "um", 1e6),
             ("z_stage_m", "z stage", "um", 1e6))


class _AxisBox(QGroupBox):
    def __init__(self, axis: str, jog: Callable[[str, float, float], object]) -> None:
        super().__init__(f"{axis} stage")
        self.axis = axis
        self.position = QLabel("–")
        self.position.setStyleSheet("font-size: 14pt; font-weight: bold")
        self.limits = QLabel("–")
        self.state = QLabel("–")
        self.step_um = QDoubleSpinBox()
        self.step_um.setRange(0.01, 1e6)
        self.step_um.setDecimals(2)
        self.step_um.setValue(10.0)
        self.step_um.setSuffix(" um")
        self.speed_um_s = QDoubleSpinBox()
        self.speed_um_s.setRange(0.01, 1e6)
        self.speed_um_s.setDecimals(2)
        self.speed_um_s.setValue(10.0)
        self.speed_um_s.setSuffix(" um/s")
        self.minus = QPushButton("◀ −")
        self.plus = QPushButton("+ ▶")
        self.minus.clicked.connect(lambda: jog(axis, -self.step_um.value() * 1e-6,
                                               self.speed_um_s.value() * 1e-6))
        self.plus.clicked.connect(lambda: jog(axis, self.step_um.value() * 1e-6,
                                              self.speed_um_s.value() * 1e-6))
        grid = QGridLayout(self)
        grid.addWidget(QLabel("position"), 0, 0)
        grid.addWidget(self.position, 0, 1, 1, 3)
        grid.addWidget(QLabel("limits"), 1, 0)
        grid.addWidget(self.limits, 1, 1, 1, 3)
        grid.addWidget(QLabel("status"), 2, 0)
        grid.addWidget(self.state, 2, 1, 1, 3)
        grid.addWidget(QLabel("jog step"), 3, 0)
        grid.addWidget(self.step_um, 3, 1)
        grid.addWidget(QLabel("speed"), 3, 2)
        grid.addWidget(self.speed_um_s, 3, 3)
        row = QHBoxLayout()
        row.addWidget(self.minus)
        row.addWidget(self.plus)
        grid.addLayout(row, 4, 0, 1, 4)


class DevicesPanel(QWidget):
    """Stages (position, limits, status, jog), readings, emergency-stop state."""

    def __init__(self, jog: JogFn | None, reset_estop: Callable[[], object] | None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._jog = jog
        self._reset = reset_estop
        self.last_snapshot: RigSnapshot | None = None
        self.source_label = QLabel("")
        self.estop_label = QLabel("e-stop: –")
        self.reset_button = QPushButton("Reset e-stop")
        self.reset_button.setToolTip("accept motion commands again (the stages stay where they are)")
        self.reset_button.clicked.connect(self._on_reset)
        self.reset_button.setEnabled(False)
        top = QHBoxLayout()
        top.addWidget(self.source_label, 1)
        top.addWidget(self.estop_label)
        top.addWidget(self.reset_button)
        self.axes = {axis: _AxisBox(axis, self.jog) for axis in AXES}
        boxes = QHBoxLayout()
        for box in self.axes.values():
            boxes.addWidget(box)
        self.readings = QLabel("readings: recorded while a run is going")
        self.readings.setWordWrap(True)
        self.jog_label = QLabel("")
        self.jog_label.setWordWrap(True)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(boxes)
        layout.addWidget(self.readings)
        layout.addWidget(self.jog_label)
        layout.addStretch(1)
        self.set_available(jog is not None, "")

    def set_available(self, available: bool, why: str) -> None:
        for box in self.axes.values():
            box.minus.setEnabled(available)
            box.plus.setEnabled(available)
        if not available and why:
            self.source_label.setText(why)

    def set_source(self, text: str) -> None:
        self.source_label.setText(text)

    def jog(self, axis: str, delta_m: float, velocity_m_s: float) -> None:
        if self._jog is None:
            return
        self.jog_label.setStyleSheet("")
        self.jog_label.setText(f"{axis}: jog {delta_m * 1e6:+.2f} um at {velocity_m_s * 1e6:.2f} um/s…")
        self._jog(axis, delta_m, velocity_m_s)

    def show_jog_result(self, ok: bool, text: str) -> None:
        self.jog_label.setText(text)
        self.jog_label.setStyleSheet(f"color: {_GREEN if ok else _RED}; font-weight: bold")

    def _on_reset(self) -> None:
        if self._reset is not None:
            self._reset()

    def show_snapshot(self, snap: RigSnapshot | None) -> None:
        self.last_snapshot = snap
        if snap is None:
            return
        for axis, st in snap.stages.items():
            box = self.axes[axis]
            box.position.setText("read failed" if math.isnan(st.position_m)
                                 else f"{st.position_m * 1e6:.2f} um")
            box.limits.setText(f"{st.min_position_m * 1e3:g} … {st.max_position_m * 1e3:g} mm, "
                               f"speed <= {st.max_velocity_m_s * 1e6:g} um/s")
            if st.error:
                box.state.setText(st.error)
                box.state.setStyleSheet(f"color: {_RED}")
            else:
                bits = ["enabled" if st.enabled else "disabled"] + (["moving"] if st.moving else []) + (
                    [f"FAULT ({st.alarm})"] if st.fault else [])
                box.state.setText(", ".join(bits))
                box.state.setStyleSheet(f"color: {_RED}" if st.fault else "")
            box.minus.setEnabled(self._jog is not None and not snap.busy)
            box.plus.setEnabled(self._jog is not None and not snap.busy)
        if snap.estop:
            self.estop_label.setText(f"E-STOP ACTIVE: {snap.estop}")
            self.estop_label.setStyleSheet(f"color: {_RED}; font-weight: bold")
        else:
            self.estop_label.setText("e-stop: not triggered")
            self.estop_label.setStyleSheet(f"color: {_GREEN}")
        self.reset_button.setEnabled(bool(snap.estop) and self._reset is not None)
        if snap.readings:
            parts = [f"{label} {snap.readings[k] * scale:.2f} {unit}" for k, label, unit, scale in _READINGS
                     if k in snap.readings]
            self.readings.setText("readings: " + ",  ".join(parts))
        elif snap.busy:
            self.readings.setText("readings: waiting for data")
        else:
            self.readings.setText("readings: recorded while a run is going; jog between runs")
