"""The operator's main window: tabs under an emergency stop that is always visible and enabled.

The emergency stop is a button above the tabs and the application-wide key **F12** (a
``Qt.ApplicationShortcut``: it works whichever tab or field has the focus, and while a run is going).
It triggers the drivers' latched emergency stop on both stages (every registered stage gets
``emergency_stop()``, motion commands are refused until it is reset) and aborts a run; in the run
service the service does this. Errors and what the e-stop did go to the status bar.
"""

from __future__ import annotations

import math

from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QCloseEvent, QKeySequence, QShortcut
from PySide6.QtWidgets import QMainWindow, QPushButton, QTabWidget, QVBoxLayout, QWidget

from rigctl.config import RigConfig
from rigctl.gui.devices_panel import DevicesPanel
from rigctl.gui.live_view import LiveView
from rigctl.gui.run_panel import RunPanel
from rigctl.gui.runs_panel import RunsPanel, fill_run_panel
from rigctl.gui.workbench_panel import WorkbenchPanel
from rigctl.rigs import OpenRig
from rigctl.runservice.devices import jog, reset_emergency_stop, snapshot
from rigctl.runservice.wire import Address

ESTOP_KEY = "F12"


class MainWindow(QMainWindow):
    """Emergency stop + tabs (Devices, Protocols, Live, Runs, Workbench)."""

    def __init__(self, config: RigConfig, backend: str = "sim", *, rig: OpenRig | None = None,
                 speed: str = "1", service: Address | None = None, config_path: str | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(f"rigctl: {config.rig.name} ({backend})")
        self.panel = RunPanel(config, backend, rig=rig, speed=speed, service=service,
                              config_path=config_path)
        self.estop_button = QPushButton(f"EMERGENCY STOP  ({ESTOP_KEY})")
        self.estop_button.setToolTip("stop both stages now; motion is refused until the e-stop is reset; "
                                     "a run is aborted")
        self.estop_button.setMinimumHeight(44)
        self.estop_button.setStyleSheet("QPushButton { background: #c62828; color: white; "
                                        "font-weight: bold; font-size: 15pt; }")
        self.estop_button.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.estop_button.clicked.connect(lambda: self.emergency_stop())
        self.estop_shortcut = QShortcut(QKeySequence(ESTOP_KEY), self)
        self.estop_shortcut.setContext(Qt.ShortcutContext.ApplicationShortcut)
        self.estop_shortcut.activated.connect(lambda: self.emergency_stop())
        self._rig = rig
        if self.panel.has_service:
            self.devices = DevicesPanel(
                lambda axis, d, v: self.panel.send_service("jog", (axis, d, v)),
                lambda: self.panel.send_service("reset_estop"))
            self.devices.set_source(f"backend {backend} in the run service (it owns the rig)")
            self.panel.signals.devices.connect(self.devices.show_snapshot)
            self.panel.signals.jog_result.connect(self.devices.show_jog_result)
        elif rig is not None:
            self.devices = DevicesPanel(self._local_jog, self._local_reset)
            self.devices.set_source(f"backend {backend}, rig opened by this window")
            self._poll = QTimer(self)
            self._poll.setInterval(400)
            self._poll.timeout.connect(self._local_snapshot)
            self._poll.start()
        else:
            self.devices = DevicesPanel(None, None)
            self.devices.set_available(False, "in-process mode: the rig is open only during a run; "
                                       "start rigctl gui without --in-process for the Devices tab")
        self.tabs = QTabWidget()
        self.tabs.addTab(self.devices, "Devices")
        self.tabs.addTab(self.panel, "Protocols")
        self.live_view = self._live_view(config)
        self.tabs.addTab(self.live_view, "Live")
        self.runs = RunsPanel()
        self.runs.run_again.connect(self._run_again)
        self.runs.status_message.connect(self.statusBar().showMessage)
        self.tabs.addTab(self.runs, "Runs")
        self.workbench = WorkbenchPanel()
        self.workbench.status_message.connect(self.statusBar().showMessage)
        self.tabs.addTab(self.workbench, "Workbench")
        self.tabs.setCurrentWidget(self.panel)
        central = QWidget()
        layout = QVBoxLayout(central)
        layout.addWidget(self.estop_button)
        layout.addWidget(self.tabs, 1)
        self.setCentralWidget(central)
        self.resize(1200, 760)
        self.statusBar().showMessage("ready")
        self.panel.status_message.connect(self.statusBar().showMessage)

    def _live_view(self, config: RigConfig) -> LiveView:
        """The Live tab, fed what the run panel receives (blocks, camera images, events, devices)."""
        view = LiveView(rate_hz=config.daq.sample_rate_hz, camera_rate_hz=config.camera.frame_rate_hz)
        sig = self.panel.signals
        sig.live_blocks.connect(view.feed_blocks)
        sig.live_frames.connect(view.feed_frames)
        sig.run_event.connect(view.add_event)
        sig.devices.connect(view.show_devices)
        sig.run_started.connect(view.start_run)
        return view

    # a rig held by this window (tests, embedding): the Devices tab reads and jogs it directly
    def _local_snapshot(self) -> None:
        if self._rig is not None:
            # during a run the readings are the latest samples of the live data this window
            # receives (in the run service, the service's acquisition gives them)
            h = self.panel.live.history
            readings = ({ch: h.latest(ch) for ch in ("ft_N", "fn_N", "delta_m")}
                        if self.panel.busy and len(h) else {})
            readings = {k: v for k, v in readings.items() if math.isfinite(v)}
            snap = snapshot(self._rig, readings, busy=self.panel.busy)
            self.devices.show_snapshot(snap)
            self.live_view.show_devices(snap)

    def _local_jog(self, axis: str, delta_m: float, velocity_m_s: float) -> None:
        assert self._rig is not None
        if self.panel.busy:
            self.devices.show_jog_result(False, "jog refused: a run is going")
            return
        try:
            jog(self._rig, axis, delta_m, velocity_m_s)
        except Exception as exc:
            self.devices.show_jog_result(False, f"jog refused: {exc}")
            return
        self.devices.show_jog_result(True, f"{axis}: moving by {delta_m * 1e6:+.1f} um")

    def _local_reset(self) -> None:
        if self._rig is not None:
            problems = reset_emergency_stop(self._rig)
            self.devices.show_jog_result(not problems, "e-stop reset" + (
                f"; alarm reset failed: {'; '.join(problems)}" if problems else ""))
            self._local_snapshot()

    def _run_again(self, protocol: str, parameters: dict[str, object]) -> None:
        """The Runs tab's "run again with these parameters": fill the Protocols tab, show it."""
        try:
            text = fill_run_panel(self.panel, protocol, parameters)
        except ValueError as exc:
            self.statusBar().showMessage(f"run again: {exc}")
            return
        self.tabs.setCurrentWidget(self.panel)
        self.statusBar().showMessage(text + "; check them and press Start")

    def emergency_stop(self, reason: str = "emergency stop by the operator") -> None:
        text = self.panel.emergency_stop(reason)
        self.statusBar().showMessage(text)

    def closeEvent(self, event: QCloseEvent) -> None:
        self.panel.closeEvent(event)  # a run going: ask, abort, close once safe
        if event.isAccepted():
            self.live_view.shutdown()
            self.runs.shutdown()
            self.workbench.shutdown()
