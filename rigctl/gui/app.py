"""`rigctl gui`: the operator's window (the run panel) on a rig backend.

The GUI's command-line options live here (:func:`add_arguments`, :func:`run_from_args`), so that
``python -m rigctl.gui.app`` and ``rigctl gui`` (:mod:`rigctl.cli.cmd_gui`, which imports them) take
the same options without the GUI importing the command line.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rigctl.errors import InputError, UsageError

if TYPE_CHECKING:
    from rigctl.config import RigConfig


def run_gui(config: RigConfig, backend: str, speed: str = "1", argv: Sequence[str] = (),
            config_path: str | None = None, in_process: bool = False) -> int:
    """Show the run panel until the window is closed; a run still going is aborted (safe state).

    Runs go to the run service (:mod:`rigctl.runservice`, started if none is listening), so a run
    outlives the window; ``in_process`` runs them in a worker thread of this process instead.
    Refuses to start (one line on stderr, exit 1) if the Qt binding fails the reference-count self-check
    (:mod:`rigctl.gui.selfcheck`): such a window would abort mid-run. Raises
    :class:`~rigctl.gui.system_libraries.SystemLibraryError` (exit 2) naming the system libraries
    Qt's ``xcb`` platform needs and cannot find, before Qt would stop on them.
    """
    from rigctl.gui import selfcheck

    check = selfcheck.check_binding()
    if check.leaking:
        print(f"rigctl gui: error: {check.message()}", file=sys.stderr)
        return 1
    from PySide6.QtWidgets import QApplication

    from rigctl.gui.main_window import MainWindow
    from rigctl.gui.system_libraries import check_xcb_libraries

    check_xcb_libraries()  # before Qt loads its platform plugin (and stops on a missing library)
    existing = QApplication.instance()
    app = existing if isinstance(existing, QApplication) else QApplication([sys.argv[0], *argv])
    from rigctl.gui.gui_thread_gc import gui_thread_collection
    from rigctl.runservice.client import ServiceStartError
    from rigctl.runservice.wire import default_address

    with gui_thread_collection():  # a worker thread must never delete the window's Qt objects
        try:
            window = MainWindow(config, backend, speed=speed, config_path=config_path,
                                service=None if in_process else default_address())
        except ServiceStartError as exc:
            print(f"rigctl gui: error: {exc}", file=sys.stderr)
            return 1
        panel = window.panel
        window.show()
        try:
            rc = app.exec()
        finally:
            if not panel.shutdown(timeout_s=60.0):  # e.g. the event loop ended by a signal
                print("rigctl gui: the run did not reach a safe state within 60 s", file=sys.stderr)
                rc = 1
            panel.disconnect_service()
        return rc


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The GUI's options: ``--backend``, ``--config``, ``--speed``, ``--in-process``; ``--screenshot``
    with ``--tab``, ``--after`` and ``--force``."""
    p.add_argument("--backend", default=None, choices=["sim", "sim-wire", "real"],
                   help="devices (default: the configuration's rig.backend)")
    p.add_argument("--config", default=None, help="rig configuration (TOML)")
    p.add_argument("--speed", default="1", help="simulated rig clock: 1, N or max")
    p.add_argument("--in-process", action="store_true",
                   help="run protocols in this process (a crash of the window then aborts the run) "
                   "instead of the run service")
    p.add_argument("--screenshot", metavar="OUT.png", default=None,
                   help="no window: run TLRE on the simulated rig for --after seconds, write a "
                   "picture of --tab to OUT.png and exit")
    p.add_argument("--tab", default="live",
                   help="the tab pictured by --screenshot, by its name in the window (devices, "
                   "protocols, live, ...; default live)")
    p.add_argument("--after", type=float, default=10.0, metavar="SECONDS",
                   help="wall time the run goes on before the picture (default 10)")
    p.add_argument("--force", action="store_true", help="replace an existing --screenshot file")


def run_from_args(args: argparse.Namespace) -> int:
    """Check the options, load the configuration, show the window; bad options raise UsageError."""
    from rigctl.config.loader import load_effective_config
    from rigctl.rigs import parse_speed

    try:
        parse_speed(args.speed)
    except InputError as exc:
        raise UsageError(str(exc)) from None
    screenshot = getattr(args, "screenshot", None)
    if screenshot is not None:
        from rigctl.gui.screenshot import check_request, take_screenshot

        if args.backend not in (None, "sim"):
            raise UsageError(f"--screenshot runs the simulated rig; --backend {args.backend} is "
                             "not taken with it")
        out = Path(screenshot).expanduser()
        check_request(out, args.after, force=args.force)
        config, _ = load_effective_config(args.config)
        return take_screenshot(config, out, args.tab, args.after, args.speed)
    config, source = load_effective_config(args.config)
    backend = args.backend or config.rig.backend
    if backend == "real" and source is None:
        raise UsageError("the real backend needs a rig configuration: --config rig.toml")
    return run_gui(config, backend, args.speed, config_path=args.config,
                   in_process=args.in_process)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rigctl.gui.app [--backend B] [--config rig.toml] [--speed S]`` (as ``rigctl gui``)."""
    parser = argparse.ArgumentParser(prog="rigctl gui", description="the operator's run panel")
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run_from_args(args)
    except InputError as exc:  # UsageError, configuration errors
        print(f"rigctl: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
