"""`rigctl` command line: one module per subcommand, each exposing ``register(subparsers)``.

Every subcommand sets ``func(args) -> int`` on its parser. Errors the user can fix (bad arguments,
bad files, limits) are :class:`~rigctl.errors.InputError` (:class:`~rigctl.errors.UsageError`,
``ConfigError``, ``DataError``, ``LimitError``, ...) and are printed as one line with exit code 2;
device failures and models that cannot be run are printed as one line with exit code 1. Any other
exception is a programming error and keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
from collections.abc import Sequence
from typing import Any

from rigctl import teardown
from rigctl.cli.streams import discard_stdout, say
from rigctl.errors import DeviceError, InputError, SimulationError, UsageError

__all__ = ["COMMAND_MODULES", "UsageError", "build_parser", "main"]

# Subcommand modules, in the order `rigctl --help` lists them. Add a line to add a command.
COMMAND_MODULES: tuple[str, ...] = (
    "rigctl.cli.cmd_simulate",
    "rigctl.cli.cmd_files",
    "rigctl.cli.cmd_config",
    "rigctl.cli.cmd_devices",
    "rigctl.cli.cmd_run",
    "rigctl.cli.cmd_gui",
    "rigctl.cli.cmd_bench",
    "rigctl.cli.cmd_model",
    "rigctl.cli.cmd_analyse",
)


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # A value starting with '-' and a digit (or -inf, -nan) is a value, not an option:
        # `--velocity -1e-5` (Python 3.11's pattern knows no exponent and reads it as an option).
        # No option of rigctl looks like a number. The pattern of CPython 3.13's argparse.
        self._negative_number_matcher = re.compile(r"-\.?\d|-(inf|infinity|nan)$", re.IGNORECASE)

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rigctl", description="Stick-slip friction rig: control, record, model.")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(name)
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; the exit code: 0 ok, 1 failed run, 2 usage or data error, 128 + the
    signal for a run ended by a signal (130 Ctrl-C, 129 SIGHUP, 131 SIGQUIT, 143 SIGTERM; also
    SIGTERM during parallel candidate fits)."""
    try:
        rc = _main(argv)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader went away (`rigctl ... | head -1`): not an error of ours, and no traceback;
        # stdout goes to /dev/null so that the interpreter's own final flush cannot fail again.
        # (`rigctl run` decides for itself: rigctl/cli/streams.py)
        discard_stdout()
        return 0
    if teardown.unsafe_to_free() and argv is None:  # a run file's close failed (disk full...)
        # The HDF5 library may crash while freeing such a file at interpreter exit, turning exit
        # code 1 into a segfault. What could be written is on disk and the error was reported:
        # leave without the library's teardown (h5py issue 914, HDF5 close-after-failed-write).
        print("rigctl: a run file could not be closed cleanly (see the error above); "
              "what was flushed before the failure is readable", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)
    return rc


class _VersionAction(argparse.Action):
    """``--version``: the versions are looked up only when asked (four package-metadata reads
    would otherwise be paid by every command at start-up)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kw: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show the versions and exit")

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(_version())
        parser.exit()


def _version() -> str:
    """``rigctl X.Y.Z (Python 3.11.x, numpy ..., h5py ..., PySide6 ...)``."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    def v(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    return (f"rigctl {v('rigctl')} (Python {platform.python_version()}, numpy {v('numpy')}, "
            f"h5py {v('h5py')}, PySide6 {v('PySide6-Essentials')})")


def _main(argv: Sequence[str] | None) -> int:
    try:
        parser = build_parser()
        if argv is None and not sys.argv[1:]:  # bare `rigctl`: the command list, not an error
            parser.print_help()
            return 2
        args = parser.parse_args(argv)
        if getattr(args, "plugins", False):
            from rigctl.model.plugins import enable_entry_points

            loaded = enable_entry_points()
            print(f"plug-in effects loaded: {', '.join(loaded) or 'none installed'}",
                  file=sys.stderr)
        return int(args.func(args))
    except InputError as exc:
        say(f"rigctl: error: {exc}")
        return 2
    except (DeviceError, SimulationError) as exc:
        say(f"rigctl: error: {exc}")
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C; SIGTERM while workers run (interrupts.Terminated);
        # a signal before a run started (run_signals.StoppedBeforeRun)
        say(f"rigctl: {str(exc) or 'interrupted'}")
        return int(getattr(exc, "exit_code", 130))


if __name__ == "__main__":
    sys.exit(main())
