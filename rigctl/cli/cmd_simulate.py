"""`rigctl simulate`: run the model headless and write a run (CSV exchange format or HDF5)."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from rigctl.errors import UsageError
from rigctl.io.load import CSV_SUFFIXES, RUN_FILE_SUFFIXES
from rigctl.io.outputs import check_output_file
from rigctl.model import Drive, ModelSpec, Simulator, build_model
from rigctl.model.drive import MAX_NORMAL_FORCE_N
from rigctl.model.plugins import effect_registry
from rigctl.model.result import SimResult


def _float(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"{what}: not a number: {text!r}") from None
    if not math.isfinite(v):
        raise UsageError(f"{what}: must be finite, got {text!r}")
    return v


def parse_segments(text: str) -> list[tuple[float, float]]:
    """'25:1e-5,20:0' -> [(25.0, 1e-5), (20.0, 0.0)] (duration_s:velocity_m_s)."""
    out = []
    for i, part in enumerate(p for p in text.split(",") if p.strip()):
        if ":" not in part:
            raise UsageError(f"--segments item {i + 1} '{part}': expected duration_s:velocity_m_s")
        d, v = part.split(":", 1)
        dur = _float(d, f"--segments item {i + 1} duration")
        if dur <= 0:
            raise UsageError(f"--segments item {i + 1}: duration must be positive, got {dur:g} s")
        out.append((dur, _float(v, f"--segments item {i + 1} velocity")))
    if not out:
        raise UsageError("--segments is empty")
    return out


def parse_effect(text: str) -> tuple[str, dict[str, float]]:
    """'rate_state:b=0.01,a=0.005' -> ('rate_state', {'b': 0.01, 'a': 0.005})."""
    name, _, rest = text.partition(":")
    params: dict[str, float] = {}
    for item in (p for p in rest.split(",") if p.strip()):
        if "=" not in item:
            raise UsageError(f"--effect {name}: '{item}' is not param=value")
        k, v = item.split("=", 1)
        params[k.strip()] = _float(v, f"--effect {name}:{k.strip()}")
    return name.strip(), params


def parse_param(text: str) -> tuple[str, float]:
    if "=" not in text:
        raise UsageError(f"--param '{text}': expected NAME=VALUE")
    k, v = text.split("=", 1)
    return k.strip(), _float(v, f"--param {k.strip()}")


def add_model_arguments(p: argparse.ArgumentParser) -> None:
    """Model options shared by commands that build a model."""
    p.add_argument("--base", default="paper", choices=["paper", "classic"])
    p.add_argument("--effect", action="append", default=[], metavar="NAME[:param=value,...]",
                   help="add an effect (repeatable)")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user effects from a Python file (repeatable)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="override a base parameter (repeatable)")
    add_plugins_argument(p)


def add_plugins_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plugins", action="store_true",
                   help="also load the effects installed packages register (rigctl.effects entry "
                        "points; off by default: their code runs only when asked)")


def model_from_args(args: argparse.Namespace) -> ModelSpec:
    registry = effect_registry(args.effect_file)
    effects = []
    eparams: dict[str, dict[str, float]] = {}
    for text in args.effect:
        name, params = parse_effect(text)
        effects.append(name)
        if params:
            eparams[name] = params
    base: dict[str, float] = {}
    for text in args.param:
        k, v = parse_param(text)
        if k in base:
            raise UsageError(f"--param {k} is given twice ({base[k]:g} and {v:g})")
        base[k] = v
    model = build_model(args.base, effects=effects, params=base, effect_params=eparams,
                        registry=registry)
    values = model.values()
    mu_s, mu_k = values.get("mu_s"), values.get("mu_k")
    if mu_s is not None and mu_k is not None and not mu_k < mu_s:
        raise UsageError(f"--param: mu_k = {mu_k:g} is not below mu_s = {mu_s:g}: the model would "
                         "make no slip")
    return model


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="run the stick-slip model headless and write a run")
    p.add_argument("--fn", type=str, default="300", help="normal force [N] (0-800)")
    p.add_argument("--velocity", type=str, default="1e-5", help="stage velocity [m/s]")
    p.add_argument("--duration", type=str, default="60", help="duration [s]")
    p.add_argument("--segments", type=str, default=None,
                   help="duration_s:velocity_m_s,... (velocity 0 = hold); replaces --velocity/"
                        "--duration")
    add_model_arguments(p)
    p.add_argument("--rate", type=str, default="1024", help="sample rate [Hz]")
    p.add_argument("--noise", action="store_true", help="add realistic sensor noise/quantisation")
    p.add_argument("--seed", type=int, default=None, help="noise seed (reproducible output)")
    p.add_argument("--out", type=Path, default=None, help="run file: .csv or .h5")
    p.add_argument("--plot", type=Path, default=None, help="PNG of Ft(t) and Ft-delta")
    p.add_argument("--force", action="store_true",
                   help="replace existing --out/--plot files (never a file being recorded)")
    p.set_defaults(func=run)


def _drive(args: argparse.Namespace) -> Drive:
    fn = _float(args.fn, "--fn")
    if fn < 0 or fn > MAX_NORMAL_FORCE_N:
        raise UsageError(f"--fn {fn:g} N is outside [0, {MAX_NORMAL_FORCE_N:g}] N")
    if args.segments:
        return Drive.segments(fn, parse_segments(args.segments))
    dur = _float(args.duration, "--duration")
    if dur <= 0:
        raise UsageError(f"--duration must be positive, got {dur:g} s")
    return Drive.constant(fn, _float(args.velocity, "--velocity"), dur)


def write_result(res: SimResult, out: Path, protocol: str) -> None:
    """Write a simulated run as CSV (exchange format) or an HDF5 run file."""
    run = res.to_measured()
    suffix = _out_suffix(out)
    if suffix in CSV_SUFFIXES:
        from rigctl.io.csv_format import write_csv

        write_csv(out, run)
    else:
        from rigctl.storage import write_measured_run

        write_measured_run(out, run, protocol=protocol, overwrite=True)


def _out_suffix(out: Path) -> str:
    """The output format by suffix; an unknown one is a UsageError."""
    suffix = out.suffix.lower()
    if suffix not in CSV_SUFFIXES + RUN_FILE_SUFFIXES:
        raise UsageError(f"--out {out}: unknown format (use .csv or .h5)")
    return suffix


MAX_RATE_HZ = 1e6
"""Highest --rate: the model's slip takes about 0.1 ms; a MHz already samples it 100 times."""
MAX_SAMPLES = 200_000_000
"""Most samples one simulation may return (7 float64 columns: about 11 GB)."""
ODD_VELOCITY_M_S = 0.1
"""Above this drive velocity (100 mm/s, 70 times this rig's fastest stage) a warning asks whether
the unit is right (mm/s typed as m/s)."""


def _check_size(drive: Drive, rate: float) -> None:
    if not 0.0 < rate <= MAX_RATE_HZ:
        raise UsageError(f"--rate {rate:g} Hz is outside (0, {MAX_RATE_HZ:g}] Hz")
    n = drive.duration_s * rate
    if n > MAX_SAMPLES:
        raise UsageError(
            f"{drive.duration_s:g} s at {rate:g} Hz is {n:.3g} samples (at most {MAX_SAMPLES:,}, "
            f"about {MAX_SAMPLES * 7 * 8 / 1e9:.0f} GB): shorten --duration or lower --rate")


def run(args: argparse.Namespace) -> int:
    drive = _drive(args)
    rate = _float(args.rate, "--rate")
    _check_size(drive, rate)
    for path, option in ((args.out, "--out"), (args.plot, "--plot")):
        if path is not None:
            check_output_file(path, option, force=args.force)
    if args.out is not None:
        _out_suffix(args.out)
    v_max = float(np.max(np.abs(np.diff(drive.x_stage_m) / np.diff(drive.t_s))))
    if v_max > ODD_VELOCITY_M_S:
        print(f"warning: drive velocity {v_max:g} m/s is {v_max * 1e3:g} mm/s: is the unit right? "
              "(velocities are in m/s)", file=sys.stderr)
    model = model_from_args(args)
    reason = model.invalid_reason((float(np.min(drive.fn_N)), float(np.max(drive.fn_N))))
    if reason is not None:
        raise UsageError(f"the model cannot stick-slip at these values: {reason} (the workbench "
                         "would refuse to fit it)")
    sim = Simulator(model, sample_rate_hz=rate)
    t0 = time.perf_counter()
    last = [0.0]

    def progress(t_done: float, t_total: float) -> None:
        now = time.perf_counter()
        if sys.stderr.isatty() and now - last[0] > 0.5:
            last[0] = now
            print(f"\rsimulating {t_done:8.1f} / {t_total:.1f} s", end="", file=sys.stderr)

    res = sim.run(drive, noise=args.noise, seed=args.seed, progress=progress)
    wall = time.perf_counter() - t0
    if sys.stderr.isatty():
        print(file=sys.stderr)
    res.metadata["protocol"] = "simulate"
    res.metadata["drive"] = args.segments or f"fn={args.fn} v={args.velocity} T={args.duration}"
    print(f"model: {model.describe()}")
    print(f"simulated {drive.duration_s:g} s in {wall:.3f} s wall, {res.n_samples} samples, "
          f"{len(res.events)} slips")
    if res.events:
        first = res.events[0]
        stable = [e for e in res.events if e.stage == "stable"]
        print(f"first slip at {first.t_start_s:.3f} s, peak {first.peak_N:.2f} N")
        if stable:
            peaks = [e.peak_N for e in stable]
            print(f"stable stage: {len(stable)} slips, peaks {min(peaks):.2f}-{max(peaks):.2f} N")
    if args.out is not None:
        write_result(res, args.out, "simulate")
        print(f"wrote {args.out}")
    if args.plot is not None:
        from rigctl.plots import plot_run

        plot_run(res, args.plot, title=model.describe())
        print(f"wrote {args.plot}")
    return 0
