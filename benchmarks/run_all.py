"""Run every benchmark: each ``benchmarks/bench_*.py`` module's ``main()``, in name order.

``python -m benchmarks.run_all [--quick] [--json] [--only NAME ...]`` (``make bench``). The flags
stay in ``sys.argv`` for the modules to read; a module that fails is reported and the others still
run; the exit code is 1 when any failed.
"""

from __future__ import annotations

import importlib
import sys
import time
import traceback
from pathlib import Path


def bench_modules() -> list[str]:
    """Importable names of the benchmark modules next to this file."""
    here = Path(__file__).resolve().parent
    return [f"benchmarks.{p.stem}" for p in sorted(here.glob("bench_*.py"))]


def _selected(argv: list[str]) -> list[str] | None:
    if "--only" not in argv:
        return None
    names = argv[argv.index("--only") + 1:]
    return [n for n in names if not n.startswith("--")]


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    only = _selected(args)
    failed: list[str] = []
    for name in bench_modules():
        short = name.removeprefix("benchmarks.bench_")
        if only is not None and short not in only:
            continue
        print(f"=== {name} ===", flush=True)
        t0 = time.perf_counter()
        try:
            code = importlib.import_module(name).main()
        except Exception:
            traceback.print_exc()
            code = 1
        print(f"--- {name}: {'ok' if not code else 'FAILED'} in {time.perf_counter() - t0:.1f} s\n",
              flush=True)
        if code:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
