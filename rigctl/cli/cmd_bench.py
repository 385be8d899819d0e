"""`rigctl bench <name>`: run one benchmark of ``benchmarks/`` and print its figures.

    rigctl bench engine [--json] [--quick]

Each benchmark is a function ``f(quick: bool) -> dict`` (JSON-able) in a ``benchmarks.bench_*``
module, optionally with a ``format_table(dict) -> str`` for the readable form. To add one, add a line
to :data:`BENCHMARKS`.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from rigctl.errors import UsageError


@dataclass(frozen=True)
class Benchmark:
    module: str
    function: str
    help: str


BENCHMARKS: dict[str, Benchmark] = {
    "engine": Benchmark(
        "benchmarks.bench_engine", "engine_benchmark",
        "model engine: real-time factor at N=10/100, speed-up vs solve_ivp(RK45), force error",
    ),
}


def _import_bench(module: str) -> ModuleType:
    """Import a benchmark module; ``benchmarks/`` lives next to the ``rigctl`` package in a source
    checkout and is not installed, so its parent directory is put on sys.path when needed."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name not in ("benchmarks", module):
            raise
    root = Path(__file__).resolve().parents[2]
    if not (root / "benchmarks" / "__init__.py").is_file():
        raise UsageError(f"benchmark module {module} not found: run from a source checkout")
    sys.path.insert(0, str(root))
    return importlib.import_module(module)


def _run(args: argparse.Namespace) -> int:
    bench = BENCHMARKS[args.bench_name]
    module = _import_bench(bench.module)
    result: dict[str, Any] = getattr(module, bench.function)(quick=args.quick)
    if args.json:
        print(json.dumps(result))
        return 0
    fmt = getattr(module, "format_table", None)
    if callable(fmt):
        print(fmt(result))
    else:
        for key, value in result.items():
            print(f"{key}: {value}")
    return 0


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("bench", help="run a benchmark and print its figures",
                                   description=__doc__.splitlines()[0] if __doc__ else None)
    sub = parser.add_subparsers(dest="bench_name", metavar="BENCHMARK",
                                parser_class=type(parser))
    sub.required = True
    for name, bench in BENCHMARKS.items():
        p = sub.add_parser(name, help=bench.help, description=bench.help)
        p.add_argument("--json", action="store_true", help="print one JSON object")
        p.add_argument("--quick", action="store_true",
                       help="fewer repeats and shorter spans (smoke run, not for the record)")
        p.set_defaults(func=_run)
