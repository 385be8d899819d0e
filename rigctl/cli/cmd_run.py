"""`rigctl run PROTOCOL`: run an experiment protocol headless and record it to a run file.

PROTOCOL is a built-in protocol's name or the path of a protocol file (``experiments.protocol_file``;
also ``--protocol-file F.py``).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rigctl.cli.run_signals import RunSignals
from rigctl.cli.streams import report, say, show
from rigctl.errors import InputError, UsageError
from rigctl.status import RunStatus

if TYPE_CHECKING:
    from experiments.protocol_file import ProtocolFile
    from experiments.protocols import Protocol


def register(sub: argparse._SubParsersAction) -> None:
    from experiments.protocols import PROTOCOLS

    p = sub.add_parser(
        "run", help="run an experiment protocol (nlre, tlre, force_sweep, velocity_steps, "
        "slide_hold_slide, or a protocol file F.py)",
        description="Protocols: " + "; ".join(f"{k}: {v.summary}" for k, v in PROTOCOLS.items())
        + ". A protocol file (a Python file defining a Protocol) is given by its path: "
        "rigctl run path/to/my_protocol.py, or --protocol-file F.py.",
    )
    p.add_argument("protocol", nargs="?", default=None,
                   help="protocol name, or the path of a protocol file (F.py)")
    p.add_argument("--protocol-file", default=None, metavar="F.py",
                   help="run the Protocol defined in this Python file (loaded from this path only)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="protocol parameter (lists comma-separated); --list-params shows them")
    p.add_argument("--backend", default=None, choices=["sim", "sim-wire", "real"],
                   help="devices (default: the configuration's rig.backend)")
    p.add_argument("--config", default=None, help="rig configuration (TOML)")
    p.add_argument("--speed", default="1", help="simulated rig clock: 1, N (faster) or max")
    p.add_argument("--out", type=Path, default=None, help="run file (default: storage folder)")
    p.add_argument("--dry-run", action="store_true", help="check limits, estimate, move nothing")
    p.add_argument("--list-params", action="store_true", help="list the protocol's parameters")
    p.add_argument("--operator", default=None)
    p.add_argument("--notes", default="")
    p.add_argument("--no-camera", action="store_true", help="do not record camera frames")
    p.add_argument("--force", action="store_true", help="overwrite an existing run file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from experiments.errors import PlanError
    from experiments.params import parse_assignments
    from rigctl.config import adapters
    from rigctl.config.loader import load_effective_config
    from rigctl.io.outputs import check_output_file
    from rigctl.rigs import open_rig, parse_speed

    signals = RunSignals()  # before anything opens or moves (rigctl/cli/run_signals.py)
    protocol, origin = _protocol(args)
    if args.list_params:
        for d in protocol.params:
            print(f"{d.name:<20} default {d.default!s:<40} [{d.unit}]  {d.doc}")
        return 0
    try:
        given = parse_assignments(args.param)
        speed = parse_speed(args.speed)
    except InputError as exc:
        raise UsageError(str(exc)) from None
    config, source = load_effective_config(args.config)
    backend = args.backend or config.rig.backend
    if backend == "real" and source is None:
        raise UsageError("the real backend needs a rig configuration: --config rig.toml")
    out = args.out
    if out is None and not args.dry_run:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        folder = Path(config.storage.directory)
        if not folder.is_dir():
            # the configured folder itself may be made, never a tree of them (a typo such as
            # /nonexistent/dir/runs is refused); an explicit --out's folder must exist
            if not folder.parent.is_dir():
                raise UsageError(f"storage.directory {folder}: its parent folder {folder.parent} "
                                 "does not exist (create it, or correct the configuration)")
            folder.mkdir()
        out = folder / f"{protocol.name}_{stamp}.h5"
    if out is not None:  # the one output policy, before the rig opens (rigctl/io/outputs.py)
        check_output_file(out, "--out", force=args.force)
    with open_rig(backend, config, speed) as rig:
        on_acquisition: list[Callable[[Any], None]] = []
        runner = rig.runner(  # built as the window and the run service build it (rigctl/rigs.py)
            protocol, given, out=out, camera=not args.no_camera, operator=args.operator,
            notes=args.notes, metadata=origin.metadata() if origin is not None else None,
            overwrite=args.force, on_acquisition=lambda acq: _each(on_acquisition, acq),
        )
        camera = runner.camera_layout
        try:
            plan, _ = runner.plan()
        except PlanError as exc:
            raise UsageError(f"dry run refused: {exc}") from None
        lines = [plan.summary()]
        if speed != float("inf"):
            lines.append(f"wall time at speed {speed:g}: ~{plan.duration_s / speed:.0f} s")
        lines.append(_file_size_line(plan.duration_s, adapters.daq_layout(rig.config), camera,
                                     out if out is not None else Path(config.storage.directory) / "x",
                                     config.storage.min_free_bytes))
        if args.dry_run:
            show([*lines, "dry run: nothing moved"])  # a reader gone meanwhile: nothing moved
            return 0
        if not show(lines):  # its reader went away before the plan was shown (`... | true`)
            raise UsageError(STDOUT_GONE)
        bar = None
        if sys.stderr.isatty():
            from rigctl.cli.progress import RunProgress

            controls = runner.controls
            bar = RunProgress([st.estimate_s for st in plan.steps], speed,
                              lambda: controls.paused)
            runner.progress = _display_only(bar.on_step)
            on_acquisition.append(bar.attach)
        signals.attach(runner, quiet_pause=bar is not None)  # from now on: safe state
        try:
            with _bar_logging(bar):
                outcome = runner.run()
        finally:
            signals.run_over()
            if bar is not None:
                _display_only(bar.close)()
    if sys.stderr.isatty():
        say("")
    st = outcome.stats
    lines = [f"{outcome.status}: {outcome.path} ({outcome.wall_s:.1f} s wall)"]
    if st is not None:
        lines.append(f"samples {st.daq_samples}, dropped {st.daq_dropped + st.queue_dropped_samples}, "
                     f"frames {st.frames} (dropped {st.frames_dropped + st.queue_dropped_frames}), "
                     f"events {st.events}, writer lag max {st.writer_lag_max_s:.3f} s")
        rate_hz = rig.config.daq.sample_rate_hz
        for channel, n in sorted(st.probe_over_range_samples.items()):
            lines.append(
                f"note: {channel} over range for {n} samples ({n / rate_hz:.1f} s): the slide "
                "carried the specimen past the probe's short range around its zero; those "
                "samples are recorded at the rail, marked 'probe_over_range' in the events and "
                "left out of every delta analysis (docs/experiments.md, 'Probes over range')")
    report(lines)  # to stderr if stdout has gone meanwhile: the exit code stays the run's
    if outcome.error:
        say(f"error: {outcome.error}")
    return {RunStatus.COMPLETED: 0, RunStatus.ABORTED: signals.exit_code}.get(outcome.status, 1)


STDOUT_GONE = ("standard output is closed (its reader went away) before the run started: nothing "
               "moved, no run file; give the run a terminal, a file or a reader that stays")
"""Why a run whose stdout has gone before motion is refused: the plan it prints is what the
operator or the scheduler sees of what the rig is about to do; nobody saw it. Once the rig moves a
closed stdout no longer matters: the run goes on to its end and its report goes to stderr."""


def _display_only(fn: Callable[..., None]) -> Callable[..., None]:
    """``fn`` for a display: a terminal that has gone (hung up) never stops the run."""
    def call(*args: Any) -> None:
        with contextlib.suppress(OSError, ValueError):
            fn(*args)

    return call


def _protocol(args: argparse.Namespace) -> tuple[Protocol[Any], ProtocolFile | None]:
    """The protocol to run: a built-in one by name, or the one a protocol file defines."""
    from experiments.protocol_file import load_protocol_file, looks_like_a_file
    from experiments.runner import get_protocol

    if args.protocol_file is not None and args.protocol is not None:
        raise UsageError(f"give either a protocol ({args.protocol}) or --protocol-file, not both")
    path = args.protocol_file
    if path is None:
        if args.protocol is None:
            raise UsageError("which protocol? give its name (e.g. tlre) or a protocol file F.py")
        if looks_like_a_file(args.protocol):
            path = args.protocol
    try:
        if path is not None:
            loaded = load_protocol_file(path)
            return loaded.protocol, loaded
        return get_protocol(args.protocol), None
    except InputError as exc:
        raise UsageError(str(exc)) from None


def _each(hooks: list[Callable[[Any], None]], acq: Any) -> None:
    for hook in hooks:
        hook(acq)


@contextlib.contextmanager
def _bar_logging(bar: Any) -> Any:
    if bar is None:
        yield
        return
    from rigctl.cli.progress import warnings_on_their_own_lines

    with warnings_on_their_own_lines():
        yield


def _file_size_line(duration_s: float, daq: Any, camera: Any, out: Path, reserve_bytes: int) -> str:
    """The run file's expected size (frames at the size measured for contact images with the
    configured compression, and at most if they do not compress), refused (UsageError) when the
    output's file system cannot hold the expected size with ``reserve_bytes`` to spare (the
    configured ``storage.min_free_bytes``, which the run itself keeps)."""
    import shutil

    from rigctl.storage import estimate_run_bytes
    from rigctl.storage.preflight import frame_bytes

    samples = estimate_run_bytes(duration_s, daq)
    total = estimate_run_bytes(duration_s, daq, camera)
    frames = total - samples
    folder = out.parent if out.parent.is_dir() else Path(".")
    free = shutil.disk_usage(folder).free
    text = f"run file: about {total / 1e6:,.0f} MB ({samples / 1e6:,.0f} MB of samples"
    if camera:
        at_most = estimate_run_bytes(duration_s, daq, camera, at_most=True)
        text += (f", {frames / 1e6:,.0f} MB of frames: {frame_bytes(camera) / 1e3:.0f} kB each "
                 f"with {camera.compression}; up to {at_most / 1e6:,.0f} MB if the images do "
                 "not compress")
    text += f"); {free / 1e9:,.1f} GB free in {folder}"
    if total + reserve_bytes > free:
        raise UsageError(f"{text}: not enough (with {reserve_bytes / 1e6:.0f} MB to spare, "
                         "storage.min_free_bytes): free space, choose another --out, or --no-camera")
    return text
