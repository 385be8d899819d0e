"""`rigctl gui`: the operator's window (the run panel) on a rig backend."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from rigctl.config import RigConfig
from rigctl.errors import InputError


def run_gui(config: RigConfig, backend: str, speed: str = "1", argv: Sequence[str] = ()) -> int:
    """Show the run panel until the window is closed; a run still going is aborted (safe state).

    Refuses to start (one line on stderr, exit 1) if the Qt binding fails the reference-count self-check
    (:mod:`rigctl.gui.selfcheck`): such a window would abort mid-run.
    """
    from rigctl.gui import selfcheck

    check = selfcheck.check_binding()
    if check.leaking:
        print(f"rigctl gui: error: {check.message()}", file=sys.stderr)
        return 1
    from PySide6.QtWidgets import QApplication

    from rigctl.gui.run_panel import RunPanel

    existing = QApplication.instance()
    app = existing if isinstance(existing, QApplication) else QApplication([sys.argv[0], *argv])
    panel = RunPanel(config, backend, speed=speed)
    panel.show()
    try:
        rc = app.exec()
    finally:
        if not panel.shutdown(timeout_s=60.0):  # e.g. the event loop ended by a signal
            print("rigctl gui: the run did not reach a safe state within 60 s", file=sys.stderr)
            rc = 1
    return rc


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rigctl.gui.app [--backend B] [--config rig.toml] [--speed S]`` (as ``rigctl gui``)."""
    import argparse

    from rigctl.cli import cmd_gui

    parser = argparse.ArgumentParser(prog="rigctl gui", description="the operator's run panel")
    cmd_gui.add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return cmd_gui.run(args)
    except InputError as exc:  # UsageError, configuration errors
        print(f"rigctl: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
