"""The operator's main window: tabs under an emergency stop that is always visible and enabled.

The emergency stop is a button above the tabs and the application-wide key **F12** (a
``Qt.ApplicationShortcut``: it works whichever tab or field has the focus, and while a run is going).
It triggers the drivers' latched emergency stop on both stages (every registered stage gets
``emergency_stop()``, motion commands are refused until it is reset) and aborts a run; in the run
service the service does this. Errors and what the e-stop did go to the status bar.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QCloseEvent, QKeySequence, QShortcut
from PySide6.QtWidgets import QMainWindow, QPushButton, QTabWidget, QVBoxLayout, QWidget

from rigctl.config import RigConfig
from rigctl.gui.run_panel import RunPanel
from rigctl.rigs import OpenRig
from rigctl.runservice.wire import Address

ESTOP_KEY = "F12"


class MainWindow(QMainWindow):
    """Emergency stop + tabs (Protocols)."""

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
        self.tabs = QTabWidget()
        self.tabs.addTab(self.panel, "Protocols")
        central = QWidget()
        layout = QVBoxLayout(central)
        layout.addWidget(self.estop_button)
        layout.addWidget(self.tabs, 1)
        self.setCentralWidget(central)
        self.resize(1200, 760)
        self.statusBar().showMessage("ready")

    def emergency_stop(self, reason: str = "emergency stop by the operator") -> None:
        text = self.panel.emergency_stop(reason)
        self.statusBar().showMessage(text)

    def closeEvent(self, event: QCloseEvent) -> None:
        self.panel.closeEvent(event)  # a run going: ask, abort, close once safe
