"""Draws docs/img/gui_runs.png, gui_workbench_residuals.png and gui_workbench.png: the GUI's Runs
and Workbench tabs with real content (docs/gui.md), rendered offscreen with ``QWidget.grab``.

Runs: a TLRE recorded by ``rigctl run tlre --speed max`` on the simulated rig, opened in the tab.
Workbench: one TLRE simulated with interface damping (which the paper's base model lacks), compared,
candidates ranked, the found effect added.

Run: ``QT_QPA_PLATFORM=offscreen .venv/bin/python docs/img/gui_runs_workbench.py`` (about a minute).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> None:
    from PySide6.QtWidgets import QApplication

    app = QApplication([])

    def wait(cond: Callable[[], bool], timeout_s: float = 300.0) -> None:
        t0 = time.monotonic()
        while not cond():
            if time.monotonic() - t0 > timeout_s:
                raise TimeoutError("the tab did not finish in time")
            app.processEvents()
            time.sleep(0.02)

    from rigctl.gui.runs_panel import RunsPanel
    from rigctl.gui.workbench_panel import WorkbenchPanel
    from rigctl.model import build_model
    from rigctl.workbench.campaigns import simulate_campaign, write_campaign

    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "tlre.h5"
        subprocess.run([sys.executable, "-m", "rigctl.cli.main", "run", "tlre", "--speed", "max",
                        "--no-camera", "--out", str(run)], check=True, capture_output=True)
        runs = RunsPanel()
        runs.resize(1280, 800)
        runs.show()
        runs.open(run)
        wait(lambda: runs._reader is None)
        runs.details.setCurrentIndex(1)  # events
        app.processEvents()
        runs.grab().save(str(HERE / "gui_runs.png"))
        runs.shutdown()

        folder = Path(tmp) / "damped"
        model = build_model("paper", effects=["interface_damping"], params={"mu_s": 0.16})
        write_campaign(simulate_campaign(model, "tlre", seed=21, duration_scale=0.6), folder)
        wb = WorkbenchPanel(workers=2)
        wb.resize(1280, 820)
        wb.show()
        wb.set_data([str(folder)])
        wb.compare()
        wait(lambda: not wb.job.running)
        wb.details.setCurrentIndex(0)  # the base model's residual map
        app.processEvents()
        wb.grab().save(str(HERE / "gui_workbench_residuals.png"))
        wb.rank(("interface_damping", "wear", "probe_drift", "stribeck", "rate_state"))
        wait(lambda: not wb.job.running)
        wb.add_effect()
        wait(lambda: not wb.job.running)
        wb.details.setCurrentIndex(1)  # ranking
        app.processEvents()
        wb.grab().save(str(HERE / "gui_workbench.png"))
        wb.shutdown()


if __name__ == "__main__":
    main()
