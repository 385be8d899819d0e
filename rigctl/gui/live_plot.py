"""The live force plots: Ft, Fn and delta against rig time, and Ft against delta.

Blocks of the 1024 Hz DAQ stream (dicts of columns as the acquisition publishes them) go into a bounded
:class:`~rigctl.gui.history.LiveHistory`; :meth:`LivePlot.redraw` hands each curve at most
``max_points`` points (min/max per bucket, :func:`~rigctl.gui.history.peak_decimate`), so the cost of a
redraw does not depend on how long the run has been going. delta = d1 - d2 (the CSV exchange format).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QVBoxLayout, QWidget

from rigctl.gui.history import LiveHistory, peak_decimate

WINDOW_S = 60.0
"""Rig time kept and shown."""
MAX_POINTS = 2400
"""Points handed to each curve per redraw (about two per horizontal pixel of a wide window)."""
CHANNELS = ("t_s", "ft_N", "fn_N", "delta_m")

_BLUE, _RED, _GREEN = "#1565c0", "#c62828", "#2e7d32"


def with_delta(block: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The block's columns plus ``delta_m = d1_m - d2_m`` (if not there already)."""
    out = dict(block)
    if "delta_m" not in out:
        out["delta_m"] = np.asarray(block["d1_m"], dtype=float) - np.asarray(block["d2_m"], dtype=float)
    return out


def _curve(plot: pg.PlotItem, color: str, name: str | None = None) -> pg.PlotCurveItem:
    """A bare curve (1-pixel cosmetic pen): the live view decimates itself, and PlotDataItem's
    per-update restyling is work (and Qt calls) a 30 fps redraw does not need."""
    curve = pg.PlotCurveItem(pen=pg.mkPen(color, width=1), name=name)
    plot.addItem(curve)
    return curve


class LivePlot(QWidget):
    """Forces against time, delta against time and Ft against delta, from a bounded history."""

    def __init__(self, rate_hz: float = 1024.0, window_s: float = WINDOW_S, max_points: int = MAX_POINTS,
                 *, phase_plot: bool = True, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window_s = window_s
        self.max_points = max_points
        self.history = LiveHistory(CHANNELS, capacity=round(window_s * rate_hz) + 1)
        self.redraws = 0
        self.last_redraw_s = 0.0
        self._t_origin = float("nan")
        self._dirty = False

        self.glw = pg.GraphicsLayoutWidget()
        self.glw.setBackground("w")
        self.force_plot = self.glw.addPlot(row=0, col=0)
        self.force_plot.setLabel("left", "force", units="N")
        self.force_plot.showGrid(x=True, y=True, alpha=0.3)
        self.force_plot.addLegend(offset=(10, 10))
        self.ft_curve = _curve(self.force_plot, _BLUE, "Ft")
        self.fn_curve = _curve(self.force_plot, _RED, "Fn")
        self.delta_plot = self.glw.addPlot(row=1, col=0)
        self.delta_plot.setLabel("left", "delta", units="m")
        self.delta_plot.setLabel("bottom", "rig time (s)")
        self.delta_plot.getAxis("bottom").enableAutoSIPrefix(False)
        self.force_plot.getAxis("bottom").setStyle(showValues=False)  # shared with delta below
        self.delta_plot.showGrid(x=True, y=True, alpha=0.3)
        self.delta_plot.setXLink(self.force_plot)
        self.delta_curve = _curve(self.delta_plot, _GREEN)
        self.phase_plot = None
        self.phase_curve = None
        if phase_plot:
            self.phase_plot = self.glw.addPlot(row=0, col=1, rowspan=2)
            self.phase_plot.setLabel("bottom", "delta", units="m")
            self.phase_plot.setLabel("left", "Ft", units="N")
            self.phase_plot.showGrid(x=True, y=True, alpha=0.3)
            self.phase_curve = _curve(self.phase_plot, _BLUE)
            self.glw.ci.layout.setColumnStretchFactor(0, 3)
            self.glw.ci.layout.setColumnStretchFactor(1, 2)
        self.glw.ci.layout.setRowStretchFactor(0, 3)
        self.glw.ci.layout.setRowStretchFactor(1, 2)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.glw)

    def clear(self) -> None:
        self.history.clear()
        self._t_origin = float("nan")
        for c in (self.ft_curve, self.fn_curve, self.delta_curve, self.phase_curve):
            if c is not None:
                c.setData([], [])
        self._dirty = False

    @property
    def samples(self) -> int:
        """Samples received since the last clear."""
        return self.history.total

    def feed(self, blocks: Iterable[Mapping[str, np.ndarray]]) -> int:
        """Append DAQ blocks (oldest first); returns the number of samples added."""
        added = 0
        for block in blocks:
            b = with_delta(block)
            if self._t_origin != self._t_origin and len(b["t_s"]):
                self._t_origin = float(b["t_s"][0])
            self.history.append(b)
            added += len(b["t_s"])
        if added:
            self._dirty = True
        return added

    def redraw(self, force: bool = False) -> bool:
        """Hand the curves the newest data (if any came since the last redraw); True if redrawn."""
        if not (self._dirty or force) or len(self.history) == 0:
            return False
        t0 = time.perf_counter()
        h = self.history
        t = h.view("t_s") - self._t_origin
        keep = int(np.searchsorted(t, t[-1] - self.window_s))
        t = t[keep:]
        ft, fn, delta = (h.view(c)[keep:] for c in ("ft_N", "fn_N", "delta_m"))
        self.ft_curve.setData(*peak_decimate(t, ft, self.max_points))
        self.fn_curve.setData(*peak_decimate(t, fn, self.max_points))
        self.delta_curve.setData(*peak_decimate(t, delta, self.max_points))
        if self.phase_curve is not None:
            step = max(1, len(t) // self.max_points)
            self.phase_curve.setData(delta[::step], ft[::step])
        self._dirty = False
        self.redraws += 1
        self.last_redraw_s = time.perf_counter() - t0
        return True
