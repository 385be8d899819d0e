"""The same benchmarks in another tree and in this one, run in turns, their headline figures compared.

``python -m benchmarks.before_after OTHER_TREE [--only engine acquisition live_view] [--rounds N]
[--timeout S] [--save FILE]`` runs each named ``benchmarks/bench_<name>.py`` with ``--quick --json``
in OTHER_TREE (its ``.venv`` python, the working directory there) and in this tree, each a fresh
process, and
prints per headline figure the median of each tree, and the ratio new/old (this tree / OTHER_TREE)
as the median of the round-by-round ratios with their smallest and largest.

The machine is shared and its load drifts: the two trees of a round run back to back, the order
turned every round (old-new, new-old, ...: a steady drift adds as much to one tree as to the
other), and each round's pair gives one ratio. A ratio range that spans 1 is noise.
Each run's process CPU seconds are figures too (``process CPU s``): what a run costs whatever the
load, where a wall-clock figure also measures the other engineers' work.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.run_all import bench_modules

HERE = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Figure:
    label: str
    path: str
    """Dotted keys into the module's JSON output; a list of cases is indexed by its ``case``."""
    higher_is_better: bool


_PROCESS = Figure("process CPU s", "_process.cpu_s", False)

HEADLINES: dict[str, list[Figure]] = {
    "engine": [
        Figure("real-time factor N=10 (median)", "realtime_factor_n10", True),
        Figure("real-time factor N=10 per CPU s", "realtime_n10.cpu_median", True),
        Figure("real-time factor N=100 (median)", "realtime_factor_n100", True),
        Figure("real-time factor N=10, warm allocator", "realtime_n10_warm_allocator.median", True),
        Figure("speed-up vs RK45", "speedup_vs_rk45", True),
        Figure("first engine call s", "first_call_s", False),
        Figure("max |Ft| error vs reference N", "max_force_error_N", False),
        _PROCESS,
    ],
    "acquisition": [
        *(f for case in ("rig-1x", "rig-10x") for f in (
            Figure(f"{case} samples/s", f"{case}.samples_per_s", True),
            Figure(f"{case} frames/s", f"{case}.frames_per_s", True),
            Figure(f"{case} dropped samples", f"{case}.dropped_samples", False),
            Figure(f"{case} dropped frames", f"{case}.dropped_frames", False),
            Figure(f"{case} writer lag max s", f"{case}.writer_lag_max_s", False),
        )),
        _PROCESS,
    ],
    "live_view": [
        Figure("frames/s at start", "start.fps", True),
        Figure("frames/s after the run", "end.fps", True),
        Figure("redraw ms median, end", "end.redraw_ms_median", False),
        Figure("paint ms median, end", "end.paint_ms_median", False),
        Figure("CPU ms a frame, start", "start.cpu_ms_per_frame", False),
        Figure("CPU ms a frame, end", "end.cpu_ms_per_frame", False),
        Figure("feeding wall s", "feed_wall_s", False),
        Figure("resident memory growth MB", "rss_growth_mb", False),
        _PROCESS,
    ],
    "compare": [
        Figure("compare wall s", "compare_wall_s", False),
        Figure("compare in evaluations", "compare_in_evaluations", False),
        Figure("one evaluation s", "evaluation_s", False),
        Figure("error E", "error", False),
        _PROCESS,
    ],
    "workbench": [
        Figure("diagnose wall s (one round)", "timing.diagnose_s", False),
        Figure("sets screened", "timing.screened", False),
        Figure("sets fitted fully", "timing.fitted", False),
        _PROCESS,
    ],
}
"""The figures compared for each module; a module not named here is compared by its CPU seconds."""

ARGS: dict[str, list[str]] = {"workbench": ["--timing-only"]}
"""Arguments a module is run with besides ``--quick --json`` (the workbench: its one round of
``diagnose``, not the hit-rate matrix)."""


def parse_output(stdout: str) -> Any:
    """The JSON document a ``--json`` benchmark printed: from its first line opening ``{`` or ``[``
    (anything printed before it is not the result)."""
    lines = stdout.splitlines()
    for i, line in enumerate(lines):
        if line.startswith(("{", "[")):
            return json.loads("\n".join(lines[i:]))
    raise ValueError("no JSON document in the benchmark's output")


def figure(doc: Any, path: str) -> float | None:
    """The number at ``path`` in ``doc``, or None where the output has no such number."""
    node = doc
    for key in path.split("."):
        if isinstance(node, list):
            node = next((c for c in node if isinstance(c, dict) and c.get("case") == key), None)
        elif isinstance(node, dict):
            node = node.get(key)
        else:
            return None
    if isinstance(node, bool) or not isinstance(node, int | float):
        return None
    return float(node)


@dataclass(frozen=True)
class Row:
    figure: Figure
    old_median: float | None
    new_median: float | None
    ratios: list[float]
    """new/old of each round where both trees gave the figure and old is not 0."""


def compare(figures: list[Figure], old: list[Any], new: list[Any]) -> list[Row]:
    """One row per figure from the rounds' outputs (``old[i]`` and ``new[i]`` ran as a pair)."""
    rows = []
    for f in figures:
        a = [figure(d, f.path) for d in old]
        b = [figure(d, f.path) for d in new]
        ratios = [y / x for x, y in zip(a, b, strict=True) if x and y is not None]
        rows.append(Row(f, _median(a), _median(b), ratios))
    return rows


def _median(values: list[float | None]) -> float | None:
    got = [v for v in values if v is not None]
    return statistics.median(got) if got else None


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}" if abs(v) < 1e5 else f"{v:,.0f}"


def format_rows(module: str, rows: list[Row], rounds: int) -> str:
    """A markdown table: figure, better, old and new medians, new/old median and range."""
    lines = [f"{module} ({rounds} rounds)", "",
             "| figure | better | old (median) | new (median) | new/old (median) | new/old (min-max) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        better = "higher" if r.figure.higher_is_better else "lower"
        if r.ratios:
            ratio = f"{statistics.median(r.ratios):.3f}"
            spread = f"{min(r.ratios):.3f}-{max(r.ratios):.3f}"
        else:
            ratio = spread = "-"
        lines.append(f"| {r.figure.label} | {better} | {_num(r.old_median)} | {_num(r.new_median)} "
                     f"| {ratio} | {spread} |")
    return "\n".join(lines)


def run_once(tree: Path, module: str, timeout_s: float) -> Any:
    """``bench_<module> --quick --json`` (and its :data:`ARGS`) in ``tree`` with its own venv;
    its output, with the process's wall and CPU seconds under ``_process``; None if it failed."""
    python = tree / ".venv" / "bin" / "python"
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        out = subprocess.run([str(python), "-m", f"benchmarks.bench_{module}", "--quick", "--json",
                              *ARGS.get(module, [])],
                             cwd=tree, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        print(f"  {tree}: {module} timed out after {timeout_s:g} s", file=sys.stderr)
        return None
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        doc = parse_output(out.stdout)
    except ValueError as e:
        print(f"  {tree}: {module} exit {out.returncode}: {e}\n{out.stderr[-2000:]}", file=sys.stderr)
        return None
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    process = {"wall_s": wall, "cpu_s": cpu}
    if isinstance(doc, list):  # a list of cases (bench_acquisition)
        return [*doc, {"case": "_process", **process}]
    return {**doc, "_process": process}


def main(argv: list[str] | None = None) -> int:
    known = [m.removeprefix("benchmarks.bench_") for m in bench_modules()]
    ap = argparse.ArgumentParser(prog="python -m benchmarks.before_after",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("other_tree", type=Path, help="the tree to compare with (the old one), with its .venv")
    ap.add_argument("--only", nargs="+", choices=known, default=["engine", "acquisition", "live_view"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=1200.0, help="seconds for one benchmark run")
    ap.add_argument("--save", type=Path, help="write every run's output here (JSON: module -> old, new)")
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    old_tree = args.other_tree.resolve()
    runs: dict[str, tuple[list[Any], list[Any]]] = {m: ([], []) for m in args.only}
    print(f"before/after: old {old_tree}, new {HERE}, {args.rounds} rounds, "
          f"load {os.getloadavg()[0]:.1f} at start ({time.strftime('%Y-%m-%d %H:%M')})", flush=True)
    for k in range(args.rounds):
        for module in args.only:
            order = [(old_tree, 0), (HERE, 1)]
            for tree, side in order if k % 2 == 0 else order[::-1]:
                print(f"round {k + 1}: {module} in {tree}", file=sys.stderr, flush=True)
                runs[module][side].append(run_once(tree, module, args.timeout))
    print(f"load {os.getloadavg()[0]:.1f} at the end ({time.strftime('%Y-%m-%d %H:%M')})\n")
    if args.save:
        args.save.write_text(json.dumps(runs, indent=1))
    for module in args.only:
        old, new = runs[module]
        print(format_rows(module, compare(HEADLINES.get(module, [_PROCESS]), old, new), args.rounds))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
