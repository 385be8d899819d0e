"""Draws docs/img/protocols_queue.png: the Protocols tab with a queue of three runs on the simulated
rig (a force sweep completed, a slide-hold-slide running, a TLRE pending), rendered offscreen with
``QWidget.grab`` (docs/gui.md, "The queue").

A run service is started for the picture (speed 10, its own runtime folder) and stopped afterwards;
the run files go to a temporary folder and are deleted.

Run: ``QT_QPA_PLATFORM=offscreen .venv/bin/python docs/img/protocols_queue.py`` (about a minute).
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
SWEEP = {"forces_N": "150, 250", "travel_m": "60e-6", "velocity_m_s": "1e-5",
         "preload_hold_s": "1", "settle_s": "1"}
SHS = {"slide_m": "40e-6", "velocity_m_s": "5e-6", "holds_s": "1, 3, 10", "preload_hold_s": "1",
       "settle_s": "1"}
TLRE = {"repetitions": "2", "travel_m": "160e-6", "velocity_m_s": "1e-5"}


def main() -> None:
    from PySide6.QtWidgets import QApplication

    from rigctl.config.loader import default_config
    from rigctl.gui.run_panel import RunPanel
    from rigctl.runservice.client import spawn_service
    from rigctl.runservice.server import service_alive
    from rigctl.runservice.wire import Address

    app = QApplication([])

    def wait(cond: Callable[[], bool], timeout_s: float = 300.0) -> None:
        t0 = time.monotonic()
        while not cond():
            if time.monotonic() - t0 > timeout_s:
                raise TimeoutError("the queue did not get there in time")
            app.processEvents()
            time.sleep(0.02)

    work = Path(tempfile.mkdtemp(prefix="rigctl-queue-picture-"))
    address = Address(work / "service")
    proc = spawn_service(address, "sim", "10", extra=["--idle-exit-s", "1"])
    try:
        wait(lambda: service_alive(address), 90.0)
        panel = RunPanel(default_config(), "sim", speed="10", service=address)
        panel.camera_check.setChecked(False)
        panel.operator_edit.setText("operator")
        for protocol, values in (("force_sweep", SWEEP), ("slide_hold_slide", SHS), ("tlre", TLRE)):
            panel.protocol_combo.setCurrentText(protocol)
            for k, v in values.items():
                panel.set_param(k, v)
            panel.out_edit.setText(str(work / f"{protocol}.h5"))
            assert panel.add_to_queue()
        wait(lambda: len(panel.queue_view.state.items) == 3)
        panel.queue_view.start_button.click()
        wait(lambda: [it.status for it in panel.queue_view.state.items][:2]
             == ["completed", "running"] and panel._progress is not None
             and panel._progress[0] >= 4)
        t0 = time.monotonic()
        wait(lambda: time.monotonic() - t0 > 3.0)  # some of the slide in the live plot
        panel.resize(1400, 900)
        wait(lambda: True)
        panel.grab().save(str(HERE / "protocols_queue.png"))
        panel.send_service("queue_abort", "picture taken")
        wait(lambda: not panel.busy and not panel.queue_view.state.running)
        panel.disconnect_service()
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(60)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
