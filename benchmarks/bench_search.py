"""The one search against the old identification chain, side by side, on held-out rigs.

``python -m benchmarks.bench_search [--cases N] [--first I] [--seed S] [--workers N] [--jsonl FILE]
[--which both|old|new]``

Cases are drawn as :mod:`benchmarks.bench_other_rigs` draws them (its rig, campaign and noise
generators; the same case for the same seed and index), restricted to controls and one-effect
cases. Identification only, no diagnosis: a control is identified as ``paper``; a one-effect case
as ``paper`` + its hidden effect (the effect given), by the old chain (``fitting.identify_model``
of the base, then ``fitting.fit_candidate`` of the effect on it) and by the new search
(``search.search_model`` of ``paper`` + effect from the preset). Each prints the error reached, the
generating model's own error on the same data, the evaluations and the wall seconds. Nothing
asserts: the figures are for the report (issue 34).

**Evaluations are counted the same way for both**: every simulation of a model on the data (every
call of :func:`rigctl.workbench.evaluate.evaluate`: starts, mass scans, ratio guesses, candidate
scans, Gauss-Newton walks, fits, Jacobians, the final evaluations and the uncertainties), in this
process and in the worker processes it forks (:class:`EvaluationCounter`). The figures the two
report themselves (``FitResult.n_evaluations``) leave some out (the old chain's scans, starts and
guesses; its second start's fit) and are printed beside them.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import multiprocessing
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import rigctl.workbench.evaluate as evaluate_module
from benchmarks.bench_other_rigs import draw_case as other_rigs_case
from benchmarks.bench_other_rigs import run_cases
from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.fitting import CandidateTask, fit_candidate, identify_model
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import search_model

HIDDEN_PATTERN = (0, 1)
"""Hidden effects per case, cycling: controls and one-effect cases (identification of a given
model; two-effect cases are a diagnosis's business)."""


def draw_case(i: int, seed: int) -> tuple[Dataset, ModelChoice, tuple[str, ...]]:
    """Case ``i`` of ``seed``: drawn by :func:`benchmarks.bench_other_rigs.draw_case` with this
    benchmark's HIDDEN_PATTERN."""
    runs, hidden, truth, _drawn = other_rigs_case(i, seed, HIDDEN_PATTERN)
    return prepare_dataset(runs), truth, hidden


class EvaluationCounter:
    """Counts the simulations of a model on the data while it is entered: every call of
    ``evaluate`` through any ``rigctl`` module that imported it, here and in forked workers (the
    count lives in shared memory; the workbench's pools fork where the platform can)."""

    def __init__(self) -> None:
        self._count: Any = multiprocessing.get_context("fork").Value("q", 0)

    @property
    def value(self) -> int:
        return int(self._count.value)

    @contextlib.contextmanager
    def counting(self) -> Iterator[None]:
        original = evaluate_module.evaluate
        count = self._count

        def counted(*args: Any, **kwargs: Any) -> Any:
            with count.get_lock():
                count.value += 1
            return original(*args, **kwargs)

        patched = [m for name, m in list(sys.modules.items()) if name.startswith("rigctl")
                   and getattr(m, "evaluate", None) is original]
        for m in patched:
            m.evaluate = counted  # type: ignore[attr-defined]
        try:
            yield
        finally:
            for m in patched:
                m.evaluate = original  # type: ignore[attr-defined]


def _counted(fn: Callable[[], Any]) -> tuple[Any, int, float]:
    """``fn()``, the simulations it ran and its wall seconds."""
    counter = EvaluationCounter()
    t0 = time.perf_counter()
    with counter.counting():
        out = fn()
    return out, counter.value, time.perf_counter() - t0


def _old(dataset: Dataset, hidden: tuple[str, ...], workers: int) -> dict[str, Any]:
    def chain() -> tuple[Any, int]:
        base = identify_model(dataset, ModelChoice("paper"), with_uncertainty=not hidden,
                              workers=workers)
        res, n = base, base.n_evaluations
        if hidden:
            res = fit_candidate(CandidateTask(dataset, base, hidden[0]), with_uncertainty=True)
            n += res.n_evaluations
        return res, n

    (res, reported), n, wall = _counted(chain)
    return {"error": res.error, "evaluations": n, "reported": reported, "wall_s": wall}


def _new(dataset: Dataset, hidden: tuple[str, ...], workers: int) -> dict[str, Any]:
    res, n, wall = _counted(lambda: search_model(dataset, ModelChoice("paper", hidden),
                                                 workers=workers))
    return {"error": res.error, "evaluations": n, "reported": res.n_evaluations,
            "message": res.message, "wall_s": wall}


NOT_RUN = {"error": math.nan, "evaluations": 0, "reported": 0, "wall_s": math.nan}
"""The row of a side not run (``--which``)."""


def run_case(i: int, seed: int, workers: int, which: str = "both") -> dict[str, Any]:
    dataset, truth, hidden = draw_case(i, seed)
    try:
        truth_err = float(evaluate(dataset, truth).score.error)
    except (SimulationError, ParameterError):
        truth_err = math.nan
    return {"case": i, "seed": seed, "hidden": list(hidden), "n_events": dataset.n_events,
            "truth_error": truth_err,
            "old": _old(dataset, hidden, workers) if which != "new" else NOT_RUN,
            "new": _new(dataset, hidden, workers) if which != "old" else NOT_RUN}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--jsonl", default="")
    ap.add_argument("--which", choices=("both", "old", "new"), default="both",
                    help="run the old chain, the new search or both (the old chain's figures "
                         "do not change with the search's code: one run of it serves to compare "
                         "two versions of the search side by side)")
    args = ap.parse_args(argv if argv is not None else
                        [a for a in sys.argv[1:] if a not in ("--quick", "--json")])
    rows = run_cases(lambda i: run_case(i, args.seed, args.workers, args.which),
                     args.first, args.cases, args.jsonl)
    print(f"{'case':>6} {'hidden':<24} {'truth':>7} {'old E':>7} {'new E':>7} {'old n':>6} "
          f"{'new n':>6} {'old s':>7} {'new s':>7}  (n: every simulation, counted alike)")
    for r in rows:
        o, n = r["old"], r["new"]
        print(f"{r['seed']}/{r['case']:<4} {','.join(r['hidden']) or '-':<24} "
              f"{r['truth_error']:7.3g} {o['error']:7.3g} {n['error']:7.3g} "
              f"{o['evaluations']:6d} {n['evaluations']:6d} {o['wall_s']:7.1f} {n['wall_s']:7.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
