"""`rigctl gui`: the operator's run panel (protocols with pause/resume/abort, progress, live forces)."""

from __future__ import annotations

import argparse

from rigctl.gui.app import add_arguments, run_from_args

__all__ = ["add_arguments", "register", "run"]

run = run_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gui", help="open the operator's run panel (Qt)",
                       description="Run protocols from a window: dry run, start, pause, resume, "
                       "abort, progress with ETA and live Ft/Fn. See docs/gui.md.")
    add_arguments(p)
    p.set_defaults(func=run)
