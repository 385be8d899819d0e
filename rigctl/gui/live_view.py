"""The Live view tab: forces, the contact camera, the run's events and its file, while a run records.

* **Forces**: Ft, Fn and delta against rig time and Ft against delta (:class:`~rigctl.gui.live_plot.
  LivePlot`: a bounded 60 s history, min/max decimation), fed the same 1024 Hz blocks the run panel
  drains from the run service; nothing is re-read from the run file.
* **Camera**: the newest downsampled contact image (a few a second, :mod:`rigctl.runservice.frames`),
  its P(x) along the sliding direction over the contact region (Han et al. 2022 Sec. 3.2, as the run
  analysis reads it: :mod:`rigctl.gui.live_contact`; 0 = back end) and Isum(t) (Eq. 1, one value per
  camera frame, full resolution) over the last 60 s of rig time.
* **Events**: the run's events and warnings as the run service and the run panel report them (start,
  pause, resume, abort, e-stop, outcome, probe over range, dropped data, device errors) and stage
  alarms and the e-stop seen in the device snapshots, each with the wall-clock time.
* **Run file**: its path, its size and the free space on its disk, refreshed every second by a
  worker thread (a stat on a slow disk never blocks the window).

Everything is redrawn by one QTimer at about 30 frames a second, and only what received new data;
feeding (:meth:`LiveView.feed_blocks`, :meth:`LiveView.feed_frames`) only appends to bounded buffers.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import math
import os
import shutil
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import QHBoxLayout, QLabel, QPlainTextEdit, QSplitter, QVBoxLayout, QWidget

from rigctl.gui.history import LiveHistory, peak_decimate
from rigctl.gui.live_contact import LiveProfile
from rigctl.gui.live_plot import MAX_POINTS, WINDOW_S, LivePlot
from rigctl.runservice.frames import LiveFrame

REDRAW_INTERVAL_MS = 30
"""At most about 33 redraws a second (a 33 ms timer gives slightly under 30 a second)."""
FILE_INFO_INTERVAL_MS = 1000
EVENT_LINES = 1000
"""Lines kept in the events pane (older ones are dropped from the view, never from the run file)."""
CAMERA_RATE_HZ = 60.0
"""Camera frame rate the Isum history is sized for (more frames just shorten the window shown)."""

RANGE_MARGIN = 0.1
"""Room left around the data when an axis range is set (fraction of the data's span)."""
RANGE_MIN_FILL = 0.4
"""An axis range is kept while the data stay inside it and fill at least this fraction of it."""

_BLUE, _RED, _ORANGE, _GREY = "#1565c0", "#c62828", "#e65100", "#555555"
_LEVEL_COLOURS = {"error": _RED, "warning": _ORANGE}


@dataclass(frozen=True)
class FileInfo:
    path: Path
    size_bytes: int | None
    free_bytes: int | None
    problem: str = ""


def file_info(path: Path) -> FileInfo:
    """Size of ``path`` and free space on its file system (None where they cannot be read)."""
    size: int | None = None
    free: int | None = None
    problems = []
    try:
        size = os.stat(path).st_size
    except OSError as exc:
        problems.append("not there yet" if isinstance(exc, FileNotFoundError) else exc.strerror or str(exc))
    try:
        free = shutil.disk_usage(path.parent if str(path.parent) else Path(".")).free
    except OSError as exc:
        problems.append(f"free space unknown: {exc.strerror or exc}")
    return FileInfo(path, size, free, "; ".join(problems))


def steady_range(current: tuple[float, float], lo: float, hi: float) -> tuple[float, float] | None:
    """A new axis range for data spanning ``lo``-``hi``, or None to keep ``current``.

    pyqtgraph's auto-range changes the range (and so regenerates the axes and paints twice) on every
    new sample; this keeps it while the data stay inside and fill at least ``RANGE_MIN_FILL`` of it,
    and otherwise sets the data's span plus ``RANGE_MARGIN`` on each side."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    span = hi - lo
    c_lo, c_hi = current
    c_span = c_hi - c_lo
    if c_lo <= lo and hi <= c_hi and span >= RANGE_MIN_FILL * c_span:
        return None
    pad = RANGE_MARGIN * span if span > 0 else max(abs(hi) * 0.05, 1e-12)
    return lo - pad, hi + pad


def format_bytes(n: int | None) -> str:
    if n is None:
        return "?"
    value = float(n)
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if value < 1000 or unit == "TB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000
    return f"{n} B"


class _Signals(QObject):
    file_info = Signal(object)  # FileInfo, from the worker thread


class LiveView(QWidget):
    """Forces, camera image with P(x) and Isum(t), events, run file: fed by the run panel."""

    def __init__(self, rate_hz: float = 1024.0, window_s: float = WINDOW_S, *,
                 camera_rate_hz: float = CAMERA_RATE_HZ, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window_s = window_s
        self.plot = LivePlot(rate_hz=rate_hz, window_s=window_s, phase_plot=True)
        self.isum_history = LiveHistory(("t_s", "isum"), capacity=round(window_s * camera_rate_hz) + 1)
        self.frames_received = 0
        """LiveFrames received since the last clear."""
        self.images_shown = 0
        self.redraws = 0
        self.last_redraw_s = 0.0
        self.fps = 0.0
        """Redraws in the last full second (0 when nothing new came)."""
        self._fps_count = 0
        self._fps_t0 = time.monotonic()
        self._frame: LiveFrame | None = None
        self.contact = LiveProfile()
        """P(x) over the contact region of the recent images."""
        self._image_dirty = False
        self._isum_dirty = False
        self._t_origin = float("nan")
        self._last_stage_state: dict[str, tuple[Any, ...]] = {}
        self._last_estop: str | None = None
        self.run_path: Path | None = None
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="live-file-info")
        self._pending: concurrent.futures.Future[FileInfo] | None = None
        self._signals = _Signals(self)
        self._signals.file_info.connect(self._show_file_info)
        self._build()
        self._timer = QTimer(self)
        self._timer.setInterval(REDRAW_INTERVAL_MS)
        self._timer.timeout.connect(self.redraw)
        self._timer.start()
        self._file_timer = QTimer(self)
        self._file_timer.setInterval(FILE_INFO_INTERVAL_MS)
        self._file_timer.timeout.connect(self._request_file_info)
        self._file_timer.start()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        cam = pg.GraphicsLayoutWidget()
        cam.setBackground("w")
        self.camera_glw = cam
        self.image_box = cam.addViewBox(row=0, col=0)
        self.image_box.setAspectLocked(True)
        self.image_box.invertY(True)
        self.image_box.setMenuEnabled(False)
        self.image_item = pg.ImageItem(axisOrder="row-major")
        self.image_item.setLevels((0, 255))
        self.image_box.addItem(self.image_item)
        self.image_label = pg.LabelItem("camera: no frame yet", size="8pt", color=_GREY)
        cam.addItem(self.image_label, row=1, col=0)
        self.profile_plot = cam.addPlot(row=2, col=0)
        self.profile_plot.setLabel("left", "P(x) (mean 1)")
        self.profile_plot.setLabel("bottom", "x in the contact (0 = back end, 1 = front end)")
        self.profile_plot.showGrid(x=True, y=True, alpha=0.3)
        self.profile_plot.setXRange(0.0, 1.0, padding=0.0)
        self.profile_curve = pg.PlotCurveItem(pen=pg.mkPen(_BLUE, width=1))
        self.profile_plot.addItem(self.profile_curve)
        self.isum_plot = cam.addPlot(row=3, col=0)
        self.isum_plot.setLabel("left", "Isum", units="grey")
        self.isum_plot.setLabel("bottom", "rig time (s)")
        self.isum_plot.getAxis("bottom").enableAutoSIPrefix(False)
        self.isum_plot.showGrid(x=True, y=True, alpha=0.3)
        self.isum_curve = pg.PlotCurveItem(pen=pg.mkPen(_RED, width=1))
        self.isum_plot.addItem(self.isum_curve)
        for plot in (self.plot.force_plot, self.plot.delta_plot, self.plot.phase_plot,
                     self.profile_plot, self.isum_plot):
            if plot is not None:
                for side in ("left", "bottom"):
                    # grid lines at the major ticks only: every tick level's grid costs most of a
                    # repaint (measured: 3x the paint time), and the redraw must stay >= 30/s
                    plot.getAxis(side).setStyle(maxTickLevel=0)
                plot.enableAutoRange(enable=False)  # ranges set by _fit_ranges, steadily
                plot.setMouseEnabled(x=False, y=False)
        layout = cam.ci.layout
        layout.setRowStretchFactor(0, 4)
        layout.setRowStretchFactor(2, 2)
        layout.setRowStretchFactor(3, 2)

        self.events = QPlainTextEdit()
        self.events.setReadOnly(True)
        self.events.setMaximumBlockCount(EVENT_LINES)
        self.events.setPlaceholderText("events and warnings of the run appear here")
        self.events.setMinimumHeight(120)  # about eight lines
        mono = QFont("monospace")
        mono.setStyleHint(QFont.StyleHint.Monospace)
        mono.setPointSize(8)
        self.events.setFont(mono)
        self.file_label = QLabel("run file: none yet")
        self.file_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.file_label.setWordWrap(True)
        self.rate_label = QLabel("")
        self.rate_label.setStyleSheet(f"color: {_GREY}")

        top = QSplitter(Qt.Orientation.Horizontal)
        top.addWidget(self.plot)
        top.addWidget(cam)
        top.setStretchFactor(0, 3)
        top.setStretchFactor(1, 2)
        bottom = QWidget()
        bl = QVBoxLayout(bottom)
        bl.setContentsMargins(0, 0, 0, 0)
        info = QHBoxLayout()
        info.addWidget(self.file_label, 1)
        info.addWidget(self.rate_label)
        bl.addLayout(info)
        bl.addWidget(self.events, 1)
        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(top)
        split.addWidget(bottom)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 1)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(4, 4, 4, 4)
        outer.addWidget(split)

    # ------------------------------------------------------------------ feeding (GUI thread, cheap)
    def clear(self) -> None:
        """Forget the previous run's data (a new run starts)."""
        self.plot.clear()
        self.isum_history.clear()
        self._t_origin = float("nan")
        self._frame = None
        self.frames_received = 0
        self.image_item.clear()
        self.profile_curve.setData([], [])
        self.contact.clear()
        self.isum_curve.setData([], [])
        self.image_label.setText("camera: no frame yet")
        self._image_dirty = self._isum_dirty = False

    def feed_blocks(self, blocks: Iterable[Mapping[str, np.ndarray]]) -> int:
        """DAQ blocks (dicts of columns with t_s, ft_N, fn_N and d1_m/d2_m or delta_m)."""
        added = self.plot.feed(blocks)
        if added and self._t_origin != self._t_origin:
            self._t_origin = self.plot._t_origin
        return added

    def feed_frames(self, frames: Iterable[LiveFrame]) -> int:
        """LiveFrames (oldest first): the newest image is shown, every Isum value is kept."""
        n = 0
        for f in frames:
            if f.isum.shape[0]:
                self.isum_history.append({"t_s": f.isum_t_s, "isum": f.isum})
                self._isum_dirty = True
            self._frame = f
            n += 1
        if n:
            self.frames_received += n
            self._image_dirty = True
        return n

    def start_run(self, path: Path | None) -> None:
        """A new run records into ``path``: forget the previous run's data, show the new file."""
        self.clear()
        self.run_path = path
        self._request_file_info()

    # ------------------------------------------------------------------ events
    def add_event(self, level: str, text: str) -> None:
        """One line in the events pane: time, level, text (warnings orange, errors red)."""
        stamp = time.strftime("%H:%M:%S")
        colour = _LEVEL_COLOURS.get(level)
        safe = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("\n", "; ")
        line = f"{stamp}  {level:<7} {safe}"
        bar = self.events.verticalScrollBar()
        following = bar.value() >= bar.maximum() - 2  # an operator reading older lines keeps them
        self.events.appendHtml(f'<span style="color:{colour}">{line}</span>' if colour else line)
        if following:
            bar.setValue(bar.maximum())

    def show_devices(self, snap: Any) -> None:
        """A device snapshot (:class:`~rigctl.runservice.devices.RigSnapshot`): stage alarms, faults,
        read errors and the e-stop become events when they change."""
        for axis, st in getattr(snap, "stages", {}).items():
            state = (bool(st.fault), str(st.alarm), str(st.error))
            before = self._last_stage_state.get(axis)
            self._last_stage_state[axis] = state
            if before is None and not (state[0] or state[2]):
                continue
            if state == before:
                continue
            if st.error:
                self.add_event("error", f"{axis} stage cannot be read: {st.error}")
            elif st.fault:
                self.add_event("error", f"{axis} stage alarm: {st.alarm}")
            elif before is not None:
                self.add_event("info", f"{axis} stage: alarm cleared")
        estop = getattr(snap, "estop", None)
        if estop != self._last_estop:
            if estop:
                self.add_event("error", f"emergency stop latched: {estop}")
            elif self._last_estop:
                self.add_event("info", "emergency stop reset")
            self._last_estop = estop

    # ------------------------------------------------------------------ drawing (GUI thread)
    def redraw(self) -> bool:
        """Redraw what received data since the last redraw; True if anything was redrawn."""
        t0 = time.perf_counter()
        drew = self.plot.redraw()
        if drew:
            self._fit_time_plots()
        if self._image_dirty and self._frame is not None:
            self._show_frame(self._frame)
            self._image_dirty = False
            drew = True
        if self._isum_dirty and len(self.isum_history):
            self._show_isum()
            self._isum_dirty = False
            drew = True
        now = time.monotonic()
        if drew:
            self.redraws += 1
            self._fps_count += 1
            self.last_redraw_s = time.perf_counter() - t0
        if now - self._fps_t0 >= 1.0:
            self.fps = self._fps_count / (now - self._fps_t0)
            self._fps_count = 0
            self._fps_t0 = now
            self.rate_label.setText(f"{self.fps:.0f} redraws/s, last {1e3 * self.last_redraw_s:.1f} ms")
        return drew

    def _fit_time_plots(self) -> None:
        p = self.plot
        x, ft = p.ft_curve.getData()
        if x is None or len(x) == 0:
            return
        t_end = float(x[-1])
        (x_lo, x_hi), _ = p.force_plot.viewRange()
        if t_end > x_hi or t_end < x_lo:  # scroll by a tenth of the window at a time
            p.force_plot.setXRange(max(t_end - self.window_s, float(x[0])),
                                   t_end + RANGE_MARGIN * self.window_s, padding=0.0)
        _fit_y(p.force_plot, ft, p.fn_curve.getData()[1])
        _fit_y(p.delta_plot, p.delta_curve.getData()[1])
        if p.phase_plot is not None and p.phase_curve is not None:
            dx, dy = p.phase_curve.getData()
            if dx is not None and len(dx):
                (c_lo, c_hi), _ = p.phase_plot.viewRange()
                new = steady_range((c_lo, c_hi), *_finite_bounds(dx))
                if new is not None:
                    p.phase_plot.setXRange(*new, padding=0.0)
                _fit_y(p.phase_plot, dy)

    def _show_frame(self, f: LiveFrame) -> None:
        self.image_item.setImage(f.image, autoLevels=False, levels=(0, 255))
        profile = self.contact.add(f.image)
        if profile is None:
            self.profile_curve.setData([], [])
        else:
            self.profile_curve.setData(self.contact.x_centres, profile)
            _fit_y(self.profile_plot, np.zeros(1), profile)
        h, w = f.image.shape[:2]
        rel = f.t_s - self._t_origin if self._t_origin == self._t_origin else f.t_s
        region = self.contact.region
        where = (f"contact in columns {region.col0 * f.factor}-{region.col1 * f.factor}"
                 if region is not None and profile is not None else "no contact visible")
        self.image_label.setText(f"camera at rig time {rel:.1f} s ({w * f.factor} x {h * f.factor} px, "
                                 f"shown at 1/{f.factor})<br>{where}")
        self.images_shown += 1

    def _show_isum(self) -> None:
        h = self.isum_history
        t = h.view("t_s")
        origin = self._t_origin if self._t_origin == self._t_origin else float(t[0])
        t = t - origin
        keep = int(np.searchsorted(t, t[-1] - self.window_s))
        ti, isum = peak_decimate(t[keep:], h.view("isum")[keep:], MAX_POINTS)
        self.isum_curve.setData(ti, isum)
        (x_lo, x_hi), _ = self.isum_plot.viewRange()
        if ti[-1] > x_hi or ti[-1] < x_lo:
            self.isum_plot.setXRange(max(ti[-1] - self.window_s, float(ti[0])),
                                     ti[-1] + RANGE_MARGIN * self.window_s, padding=0.0)
        _fit_y(self.isum_plot, isum)

    # ------------------------------------------------------------------ run file (worker thread)
    def _request_file_info(self) -> None:
        path = self.run_path
        if path is None:
            return
        if self._pending is not None and not self._pending.done():
            return  # the previous stat is still going (a slow disk): never queue up
        fut = self._pool.submit(file_info, path)
        fut.add_done_callback(self._deliver)
        self._pending = fut

    def _deliver(self, fut: concurrent.futures.Future[FileInfo]) -> None:
        if not fut.cancelled() and fut.exception() is None:
            with contextlib.suppress(RuntimeError):  # the window went away meanwhile
                self._signals.file_info.emit(fut.result())  # queued into the GUI thread

    def _show_file_info(self, info: FileInfo) -> None:
        if info.path != self.run_path:
            return
        text = (f"run file: {info.path}   size {format_bytes(info.size_bytes)}   "
                f"free on its disk {format_bytes(info.free_bytes)}")
        if info.problem:
            text += f"   ({info.problem})"
        self.file_label.setText(text)

    def shutdown(self) -> None:
        """Stop the timers and the file-info worker (the window is closing)."""
        self._timer.stop()
        self._file_timer.stop()
        self._pool.shutdown(wait=False, cancel_futures=True)


def _finite_bounds(*arrays: np.ndarray | None) -> tuple[float, float]:
    """Smallest and largest finite value of the arrays (NaN, NaN if there is none)."""
    values = [a[np.isfinite(a)] for a in arrays if a is not None and len(a)]
    values = [v for v in values if v.size]
    if not values:
        return math.nan, math.nan
    return min(float(v.min()) for v in values), max(float(v.max()) for v in values)


def _fit_y(plot: pg.PlotItem, *arrays: np.ndarray | None) -> None:
    _, current = plot.viewRange()
    new = steady_range((float(current[0]), float(current[1])), *_finite_bounds(*arrays))
    if new is not None:
        plot.setYRange(*new, padding=0.0)
