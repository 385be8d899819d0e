"""Does the record's noise change which slips are read? ``bench_other_rigs`` cases, each read as
recorded and as its noise-free twin read with the record's own settings.

``python -m benchmarks.reading_noise --seed S [--cases N] [--first I] [--results RESULTS.jsonl]``

The workbench reads a model's noise-free series with the measured record's settings
(:func:`rigctl.workbench.evaluate.read_result`). Where the record's noise changes which slips
that reading finds (a drop whose delta jump is near the confirmation's level, a drop near the
force threshold), even the generating model cannot match the record, and a case looks
undecidable for a reason that is the reading, not the data (docs/validation.md, "Known
weaknesses"). Per case this prints the slips read in the record and in its noise-free twin, and
the runs where they differ; with ``--results`` (the case's ``bench_other_rigs`` JSON lines) also
its answer and whether the generating model halves the base's error.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from benchmarks.bench_other_rigs import draw_case
from benchmarks.held_out_table import load
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.evaluate import read_result


def slips_read(seed: int, case: int) -> list[tuple[str, int, int]]:
    """Per run of the case: its name, the slips read in the record and in the noise-free twin
    read with the record's settings."""
    noisy, _, _, _ = draw_case(case, seed)
    clean, _, _, _ = draw_case(case, seed, noisy=False)
    twins = {run.source: run for run in clean}
    out = []
    for run in prepare_dataset(noisy).runs:
        events = read_result(twins[run.name], run)
        out.append((run.name, len(run.events.features["drop_N"]),
                    len(events.features["drop_N"])))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--cases", type=int, default=24)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--results", help="the seed's bench_other_rigs JSON lines (answers)")
    args = ap.parse_args(argv)
    results: dict[int, dict[str, Any]] = {
        int(c["case"]): c for c in (load([args.results]) if args.results else [])}
    differ = 0
    for case in range(args.first, args.first + args.cases):
        runs = slips_read(args.seed, case)
        rec, twin = sum(r for _, r, _ in runs), sum(t for _, _, t in runs)
        changed = [f"{name} {r}/{t}" for name, r, t in runs if r != t]
        differ += bool(changed)
        res = results.get(case)
        said = "" if res is None else (
            f"{res['answer']:<17} generating model halves the base: "
            f"{'yes' if res['truth_error'] <= 0.5 * res['baseline_error'] else 'no ':<3} ")
        print(f"case {case:3d} {said}slips read {rec} (record) / {twin} (noise-free); "
              f"differ in: {', '.join(changed) or '-'}", flush=True)
    print(f"{differ} of {args.cases} cases read different slips with and without the record's "
          "noise", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
