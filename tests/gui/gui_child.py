"""A GUI process for tests: the run panel on a run service, starts a short TLRE, prints each step.

``python tests/gui/gui_child.py RUNTIME_DIR OUT.h5`` (QT_QPA_PLATFORM=offscreen); the test SIGKILLs it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from PySide6.QtWidgets import QApplication

from rigctl.config.loader import default_config
from rigctl.gui.gui_thread_gc import collect_in_gui_thread
from rigctl.gui.run_panel import RunPanel
from rigctl.runservice.wire import Address

PARAMS = {"repetitions": "1", "travel_m": "400e-6", "velocity_m_s": "1e-5", "preload_hold_s": "1",
          "settle_s": "1"}


def main() -> int:
    app = QApplication([sys.argv[0]])
    collect_in_gui_thread()  # as `rigctl gui` does
    panel = RunPanel(default_config(), "sim", speed="10", service=Address(Path(sys.argv[1])))
    panel.camera_check.setChecked(False)
    panel.protocol_combo.setCurrentText("tlre")
    for k, v in PARAMS.items():
        panel.set_param(k, v)
    panel.out_edit.setText(sys.argv[2])
    panel._sig.progress.connect(lambda i, n, desc, *rest: print(f"step {i}/{n}: {desc}", flush=True))
    panel.show()
    panel.start_button.click()
    return app.exec()


if __name__ == "__main__":
    sys.exit(main())
