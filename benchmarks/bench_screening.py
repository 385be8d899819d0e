"""Does a screen keep the hidden effects? The score screen and short fits on held-out rigs.

``python -m benchmarks.bench_screening [--cases N] [--first I] [--seed S] [--workers N]
[--short] [--jsonl FILE]``

Cases are :func:`benchmarks.bench_other_rigs.draw_case`'s (the same case for the same seed and
index: controls, one and two hidden effects). For each, the base ``paper`` is identified by the one
search (:func:`rigctl.workbench.search.search_model`), then every library effect it lacks is
screened on it by the score screen (:func:`rigctl.workbench.screening.score_screen`) and, with
``--short``, by short fits (the search on 60 evaluations, :func:`rigctl.workbench.selection.
screen_sets`). Each line gives each hidden effect's rank in each screen, whether it is kept (rank
within ``SCREEN_KEEP``; a two-effect case also whether both are among the ``PAIR_POOL`` singles
that pairs are formed from), the evaluations and the seconds. A control gives the best screened
error against the base's. Nothing asserts: the figures are for the report.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from benchmarks.bench_other_rigs import draw_case, run_cases
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.budget import Budget
from rigctl.workbench.model_choice import ModelChoice, candidate_effects
from rigctl.workbench.screening import score_screen
from rigctl.workbench.search import search_model
from rigctl.workbench.selection import PAIR_POOL, SCREEN_KEEP, screen_sets

SHORT_FIT_EVALUATIONS = 60
"""The short fit's budget: the search's starts and two to three polish Jacobians."""


def _ranks(order: list[tuple[str, ...]], hidden: tuple[str, ...]) -> dict[str, int]:
    return {h: 1 + order.index((h,)) for h in hidden if (h,) in order}


def _summary(order: list[tuple[str, ...]], errors: list[float], hidden: tuple[str, ...],
             base_error: float) -> dict[str, Any]:
    ranks = _ranks(order, hidden)
    out: dict[str, Any] = {"ranks": ranks, "best": list(order[0]), "best_error": errors[0],
                           "base_error": base_error}
    if hidden:
        out["kept"] = all(r <= SCREEN_KEEP for r in ranks.values()) if len(hidden) == 1 else \
            any(r <= SCREEN_KEEP for r in ranks.values())
        out["pair_formed"] = len(hidden) == 2 and all(r <= PAIR_POOL for r in ranks.values())
    return out


def run_case(i: int, seed: int, workers: int, short: bool) -> dict[str, Any]:
    runs, hidden, _truth, drawn = draw_case(i, seed)
    ds = prepare_dataset(runs)
    t0 = time.perf_counter()
    base = search_model(ds, ModelChoice("paper"), workers=workers, with_uncertainty=False)
    t_base = time.perf_counter() - t0
    pool = [(c,) for c in candidate_effects(ModelChoice("paper"))]
    budget = Budget()
    t0 = time.perf_counter()
    screened = score_screen(ds, base, pool, workers=workers, budget=budget)
    res: dict[str, Any] = {
        "case": i, "seed": seed, "hidden": list(hidden), "n_events": ds.n_events,
        "rate_hz": drawn["rate_hz"], "base_s": round(t_base, 1),
        "score": {**_summary([s.effects for s in screened], [s.error for s in screened], hidden,
                             base.error),
                  "evaluations": budget.used, "wall_s": round(time.perf_counter() - t0, 1)}}
    if short:
        short_budget = Budget()

        def fit(d: Any, c: ModelChoice) -> Any:
            b = Budget(max_evaluations=SHORT_FIT_EVALUATIONS)
            out = search_model(d, c, budget=b, workers=workers, with_uncertainty=False)
            short_budget.spend(b.used)
            return out

        t0 = time.perf_counter()
        ranked = screen_sets(ds, base, pool, screen=fit)
        res["short"] = {**_summary([s.effects for s in ranked], [s.error for s in ranked],
                                   hidden, base.error),
                        "evaluations": short_budget.used,
                        "wall_s": round(time.perf_counter() - t0, 1)}
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--short", action="store_true", help="also screen by short fits")
    ap.add_argument("--jsonl", default="")
    args = ap.parse_args(argv)
    results = run_cases(lambda i: run_case(i, args.seed, args.workers, args.short),
                        args.first, args.cases, args.jsonl)
    with_hidden = [r for r in results if r["hidden"]]
    for key in ("score", "short"):
        got = [r[key] for r in with_hidden if key in r]
        if got:
            print(f"{key}: kept {sum(g['kept'] for g in got)}/{len(got)}, "
                  f"{sum(g['evaluations'] for g in got)} evaluations, "
                  f"{sum(g['wall_s'] for g in got):.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
