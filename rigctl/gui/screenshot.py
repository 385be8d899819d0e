"""`rigctl gui --screenshot OUT.png --tab NAME`: a picture of one tab of the window during a run.

The window is built on a simulated rig that it holds itself (no run service), TLRE (the paper's
stick-slip experiment, default parameters) is started from the Protocols tab into a temporary run
file, and after ``after_s`` seconds of wall time, the live view drawing all the while, the window
with the chosen tab in front is rendered (``QWidget.grab``) and written to OUT (a temporary name,
then renamed: a failed write leaves an older file intact). The run is then aborted (safe state) and
its temporary file removed. Tab names are read from the window's QTabWidget (lower case), so every
tab the window has can be pictured.

Qt draws offscreen unless ``QT_QPA_PLATFORM`` says otherwise: no screen is needed.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from rigctl.errors import UsageError

if TYPE_CHECKING:
    from PySide6.QtWidgets import QTabWidget

    from rigctl.config import RigConfig

PROTOCOL = "tlre"
"""The protocol run while the window is pictured."""
MAX_AFTER_S = 24 * 3600.0


def tab_names(tabs: QTabWidget) -> dict[str, int]:
    """The tabs' names in lower case (``&`` accelerators removed), to their indices."""
    return {tabs.tabText(i).replace("&", "").strip().lower(): i for i in range(tabs.count())}


def check_request(out: Path, after_s: float, *, force: bool) -> None:
    """Refuse (UsageError) a screenshot that cannot be made, before anything starts."""
    from rigctl.io.outputs import check_output_file

    if out.suffix.lower() != ".png":
        raise UsageError(f"--screenshot {out}: the picture is written as PNG; name it *.png")
    if not (math.isfinite(after_s) and 0.0 <= after_s <= MAX_AFTER_S):
        raise UsageError(f"--after {after_s:g}: seconds of wall time between 0 and {MAX_AFTER_S:.0f}")
    check_output_file(out, "--screenshot", force=force)


def write_png(widget_pixmap: object, out: Path) -> None:
    """Save a QPixmap as PNG under a temporary name beside ``out``, then rename it into place."""
    from PySide6.QtGui import QPixmap

    assert isinstance(widget_pixmap, QPixmap)
    directory = out.parent if str(out.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".png", dir=directory)
    os.close(fd)
    try:
        if not widget_pixmap.save(tmp, "PNG"):
            raise UsageError(f"--screenshot {out}: the picture could not be written")
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def take_screenshot(config: RigConfig, out: Path, tab: str, after_s: float, speed_text: str,
                    argv: list[str] | None = None) -> int:
    """Run TLRE on the simulated rig for ``after_s`` s of wall time, picture tab ``tab`` into ``out``.

    Returns 0, or 1 (one line on stderr) if the Qt binding fails its self-check or the run failed;
    raises UsageError for an unknown tab or an output that cannot be written.
    """
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from rigctl.gui import selfcheck

    check = selfcheck.check_binding()
    if check.leaking:
        print(f"rigctl gui: error: {check.message()}", file=sys.stderr)
        return 1
    from PySide6.QtWidgets import QApplication

    from rigctl.gui.gui_thread_gc import gui_thread_collection
    from rigctl.gui.main_window import MainWindow
    from rigctl.rigs import open_rig, parse_speed

    existing = QApplication.instance()
    app = existing if isinstance(existing, QApplication) else QApplication([sys.argv[0], *(argv or [])])
    # the collection first: the run thread must never delete the window's Qt objects
    with gui_thread_collection(), \
            tempfile.TemporaryDirectory(prefix="rigctl-screenshot-") as tmp, \
            open_rig("sim", config, parse_speed(speed_text)) as rig:
        window = MainWindow(config, "sim", rig=rig)
        panel = window.panel
        try:
            names = tab_names(window.tabs)
            wanted = tab.strip().lower()
            if wanted not in names:
                raise UsageError(f"--tab {tab!r}: no such tab; the window's tabs are "
                                 f"{', '.join(names)}")
            panel.protocol_combo.setCurrentText(PROTOCOL)
            panel.out_edit.setText(str(Path(tmp) / f"screenshot_{PROTOCOL}.h5"))
            window.resize(1400, 900)
            window.tabs.setCurrentIndex(names[wanted])
            window.show()
            panel.start_button.click()
            deadline = time.monotonic() + after_s
            while time.monotonic() < deadline:
                app.processEvents()
                time.sleep(0.005)
            app.processEvents()
            window.live_view.redraw()
            panel.live.redraw()
            write_png(window.grab(), out)
            outcome = panel.last_outcome
        finally:
            safe = panel.shutdown(timeout_s=60.0)
            window.live_view.shutdown()
            window.hide()
            window.deleteLater()
            app.processEvents()
    if not safe:
        print("rigctl gui: error: the run did not reach a safe state within 60 s", file=sys.stderr)
        return 1
    if outcome is not None and outcome.status == "failed":
        print(f"rigctl gui: error: the run failed before the picture was taken: {outcome.error}",
              file=sys.stderr)
        return 1
    return 0
