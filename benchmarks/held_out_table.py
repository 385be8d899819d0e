"""The validation table of a ``bench_other_rigs`` run, generated from its JSON lines.

``python -m benchmarks.held_out_table RESULTS.jsonl [...] --title "..." [--out FILE]``

Each line is one case as :func:`benchmarks.bench_other_rigs.run_case` wrote it. The table lists
every case (what was hidden, what ``--auto`` ended with, its answer, the errors and the time) and
sums them: hits with their 95 % Clopper-Pearson interval (exact binomial,
``scipy.stats.binomtest``), the indistinguishable answers counted apart from the wrong names, and
the median and worst time per case. The tables in docs/validation/ are this script's output, not
edited by hand.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from collections.abc import Sequence
from typing import Any

from scipy.stats import binomtest


def load(paths: Sequence[str]) -> list[dict[str, Any]]:
    """The cases of ``paths`` (JSON lines), by case index; a case run twice keeps its last line."""
    cases: dict[int, dict[str, Any]] = {}
    for path in paths:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                if line.strip():
                    case = json.loads(line)
                    cases[int(case["case"])] = case
    return [cases[i] for i in sorted(cases)]


def interval(k: int, n: int) -> tuple[float, float]:
    """The 95 % Clopper-Pearson interval of k successes in n trials."""
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return float(ci.low), float(ci.high)


def answer(case: dict[str, Any]) -> str:
    """``hit``, ``indistinguishable``, ``time limit`` (cancelled at the case time limit: a miss
    with no name) or ``wrong`` (older lines have only ``hit``)."""
    if "answer" in case:
        return str(case["answer"])
    return "hit" if case["hit"] else "wrong"


def _names(effects: Sequence[str]) -> str:
    return ", ".join(effects) if effects else "-"


def _err(x: float | None) -> str:
    return f"{x:.3g}" if x is not None and math.isfinite(x) else "-"


def _memory_line(cases: Sequence[dict[str, Any]]) -> list[str]:
    """The run's peak resident memory (lines written since it was recorded), or nothing."""
    peaks = [c["peak_rss_mb"] for c in cases if "peak_rss_mb" in c]
    if not peaks:
        return []
    parent = max(float(p["parent"]) for p in peaks)
    worker = max(float(p["largest_worker"]) for p in peaks)
    return [f"- Peak resident memory over the run: {parent:.0f} MB (the diagnosing process), "
            f"{worker:.0f} MB (its largest worker process)."]


def table(cases: Sequence[dict[str, Any]], title: str) -> str:
    """The markdown page: the summary, then a row per case."""
    n = len(cases)
    kinds = [answer(c) for c in cases]
    hits, undecided = kinds.count("hit"), kinds.count("indistinguishable")
    stopped = kinds.count("time limit")
    wrong = n - hits - undecided - stopped
    walls = [float(c["wall_s"]) for c in cases]
    lines = [f"# {title}", ""]
    if n:
        lo, hi = interval(hits, n)
        lines += [
            f"- **Hits: {hits} of {n}** ({hits / n:.0%}; 95 % interval {lo:.2f}-{hi:.2f}, "
            "Clopper-Pearson).",
            f"- Indistinguishable (the data could not decide; counted apart): {undecided}"
            + (f", of which the hidden set was among the contenders in "
               f"{sum(bool(c.get('truth_among_undecided')) for c in cases)}" if undecided
               else "") + f". Wrong names: {wrong}."
            + (f" Stopped at the case time limit (no answer, a miss): {stopped}." if stopped
               else ""),
        ]
        limited = sum(bool(c.get("run_time_limited")) for c in cases)
        if limited:
            lines.append(f"- Ended by the run's own time limit (`--max-time`; the model it had "
                         f"is the answer, judged like any other): {limited}.")
        by_hidden: dict[int, list[str]] = {}
        for c, k in zip(cases, kinds, strict=True):
            by_hidden.setdefault(len(c["hidden"]), []).append(k)
        parts = [f"{('controls', 'one effect', 'two effects')[h] if h < 3 else f'{h} effects'} "
                 f"{ks.count('hit')}/{len(ks)}" for h, ks in sorted(by_hidden.items())]
        lines += [f"- By what was hidden: {'; '.join(parts)}.",
                  f"- Time per case: median {statistics.median(walls):.0f} s, worst "
                  f"{'at least ' if stopped else ''}{max(walls):.0f} s (wall, `--workers 2`"
                  f"{'; a case stopped at the limit counts its limit' if stopped else ''}).",
                  *_memory_line(cases), ""]
    lines += ["| case | hidden | final model's effects | answer | baseline E | final E | "
              "generating model's E | wall s |",
              "| ---: | --- | --- | --- | ---: | ---: | ---: | ---: |"]
    for c, k in zip(cases, kinds, strict=True):
        shown = k if k != "indistinguishable" else \
            f"indistinguishable ({' / '.join(c.get('undecided_between', []))})"
        if c.get("run_time_limited"):
            shown += " (run time limit)"
        lines.append(f"| {c['case']} | {_names(c['hidden'])} | {_names(c['final'])} | {shown} | "
                     f"{_err(c.get('baseline_error'))} | {_err(c.get('final_error'))} | "
                     f"{_err(c.get('truth_error'))} | {float(c['wall_s']):.0f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("jsonl", nargs="+")
    ap.add_argument("--title", default="Held-out rigs")
    ap.add_argument("--out", default="", help="write the page here (default: standard output)")
    args = ap.parse_args(argv)
    page = table(load(args.jsonl), args.title)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(page)
    else:
        sys.stdout.write(page)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
