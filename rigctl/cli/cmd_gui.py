"""`rigctl gui`: the operator's run panel (protocols with pause/resume/abort, progress, live forces)."""

from __future__ import annotations

import argparse

from rigctl.errors import InputError, UsageError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gui", help="open the operator's run panel (Qt)",
                       description="Run protocols from a window: dry run, start, pause, resume, "
                       "abort, progress with ETA and live Ft/Fn. See docs/gui.md.")
    add_arguments(p)
    p.set_defaults(func=run)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--backend", default=None, choices=["sim", "sim-wire", "real"],
                   help="devices (default: the configuration's rig.backend)")
    p.add_argument("--config", default=None, help="rig configuration (TOML)")
    p.add_argument("--speed", default="1", help="initial simulated rig clock: 1, N or max")


def run(args: argparse.Namespace) -> int:
    from rigctl.config.loader import load_effective_config
    from rigctl.rigs import parse_speed

    try:
        parse_speed(args.speed)
    except InputError as exc:
        raise UsageError(str(exc)) from None
    config, source = load_effective_config(args.config)
    backend = args.backend or config.rig.backend
    if backend == "real" and source is None:
        raise UsageError("the real backend needs a rig configuration: --config rig.toml")
    from rigctl.gui.app import run_gui

    return run_gui(config, backend, args.speed)
