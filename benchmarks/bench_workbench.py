"""Workbench benchmark: diagnose speed, and the hidden-effect hit rate over a matrix of campaigns.

``python -m benchmarks.bench_workbench [--quick] [--json] [--timing-only] [--matrix-only]
[--workers N] [--effects a,b] [--paired] [--out FILE] [--jsonl FILE [--resume]]``

* timing: ``diagnose`` on the ``classic`` base (all 12 library effects are candidates: screened,
  the promising ones fitted fully by the search, ``--workers`` default 2) of a 5-run force sweep,
  5 x 40 s = 200 s of 1024 Hz data with sensor noise, generated with ``load_dependent_friction``
  hidden; wall time, the sets screened and the wall seconds of each full fit.
* matrix: for every library effect, campaigns from the simulator with that effect hidden (the
  protocol of ``PROTOCOL_FOR_EFFECT``), at 0.5x and 2x the effect's typical magnitude (its default
  minus its off value) on two base parameter sets, with realistic noise; plus controls (no effect)
  for every protocol and base set. Every case is diagnosed against the whole library. A case is a
  hit when the verdict names the hidden effect (``none`` for a control) and, for an effect, adding
  it cuts the error by at least half. ``--quick``: magnitude 1x on one base set. ``--jsonl``
  appends each case as it finishes; with ``--resume`` the cases already in it are skipped.
  ``--paired``: half the crossed design with the same seeds (0.5x on the ``paper`` set and 2x on
  the ``alt`` set; controls alternate the sets) - what fits in an hour on a shared 2-core machine.

The conditions differ from the tests' (tests/workbench/hidden.py): other base parameters, other
magnitudes, the protocols' nominal velocity and durations, other seeds, the full library.
Figures are printed (and written as JSON with ``--out``); nothing here asserts a time.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from dataclasses import asdict, dataclass, field
from typing import Any

from rigctl.model import build_model, effect_names
from rigctl.model.effects import LIBRARY
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, PROTOCOLS, simulate_campaign
from rigctl.workbench.diagnose import diagnose
from rigctl.workbench.model_choice import ModelChoice

BASE_SETS: dict[str, dict[str, float]] = {
    "paper": {},
    "alt": {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
            "mu_smax": 0.21},
}
MAGNITUDES = (0.5, 2.0)


@dataclass
class Case:
    effect: str
    protocol: str
    magnitude: float
    base_set: str
    seed: int
    verdict: str = ""
    candidates: tuple[str, ...] = ()
    baseline_error: float = float("nan")
    best_error: float = float("nan")
    reduction: float = float("nan")
    hit: bool = False
    seconds: float = 0.0
    ranking: list[tuple[str, float, float, bool]] = field(default_factory=list)


def effect_values(effect: str, magnitude: float, base: dict[str, float]) -> dict[str, float]:
    """The effect's identified parameters at ``magnitude`` times their typical deviation."""
    eff = LIBRARY[effect]()
    base_full = {"mu_s": 0.15, "kts_N_per_m": 0.9e6, **base}
    offs = eff.off_values(base_full)
    out = {}
    for p in eff.params:
        if not p.identify:
            continue
        off = offs[p.name]
        out[p.name] = min(max(off + magnitude * (p.default - off), p.lower), p.upper)
    return out


def run_case(case: Case, workers: int | None = 2) -> Case:
    base = BASE_SETS[case.base_set]
    if case.effect == "none":
        model = build_model("paper", params=base)
        diag_base = "paper"
    elif case.effect == "stress_evolution":
        vals = effect_values("stress_evolution", case.magnitude, base)
        model = build_model("paper", params={**base, **vals})
        diag_base = "classic"
    else:
        model = build_model("paper", effects=[case.effect], params=base,
                            effect_params={case.effect: effect_values(case.effect,
                                                                      case.magnitude, base)})
        diag_base = "paper"
    runs = simulate_campaign(model, case.protocol, seed=case.seed)
    t0 = time.perf_counter()
    ds = prepare_dataset(runs)
    diag = diagnose(ds, ModelChoice(diag_base), workers=workers)
    case.seconds = time.perf_counter() - t0
    r0 = diag.first
    case.verdict = r0.verdict.verdict
    case.candidates = tuple(r0.verdict.candidates)
    case.baseline_error = r0.model.error
    if case.effect == "none":
        case.hit = case.verdict == "none"
    else:
        hidden = next((s for s in r0.ranking if s.effect == case.effect), None)
        if hidden is not None:
            case.best_error = hidden.error
            case.reduction = hidden.error_reduction
        case.hit = case.verdict == case.effect and case.reduction >= 0.5
    case.ranking = [(s.effect, round(s.error, 4), round(s.delta_bic, 1), s.significant)
                    for s in r0.ranking]
    return case


def matrix_cases(quick: bool, effects: list[str] | None = None,
                 paired: bool = False) -> list[Case]:
    cases: list[Case] = []
    seed = 100
    mags = (1.0,) if quick else MAGNITUDES
    sets = ("paper",) if quick else tuple(BASE_SETS)
    for effect in effect_names():
        for m in mags:
            for bs in sets:
                seed += 1
                cases.append(Case(effect, PROTOCOL_FOR_EFFECT[effect], m, bs, seed))
    for protocol in PROTOCOLS:
        for bs in sets:
            seed += 1
            cases.append(Case("none", protocol, 0.0, bs, seed))
    if effects:
        cases = [c for c in cases if c.effect in effects]
    if paired:
        # half the crossed design, same seeds: each effect at 0.5x on one base set and 2x on the
        # other; controls alternate base sets over the protocols
        keep = {(0.5, "paper"), (2.0, "alt")}
        ctrl = {p: ("paper", "alt")[i % 2] for i, p in enumerate(PROTOCOLS)}
        cases = [c for c in cases if (c.effect != "none" and (c.magnitude, c.base_set) in keep)
                 or (c.effect == "none" and c.base_set == ctrl[c.protocol])]
    return cases


def _done(jsonl: str | None) -> set[tuple[str, str, float, str]]:
    if not jsonl or not os.path.exists(jsonl):
        return set()
    with open(jsonl, encoding="utf-8") as fh:
        rows = [json.loads(line) for line in fh if line.strip()]
    return {(r["effect"], r["protocol"], float(r["magnitude"]), r["base_set"]) for r in rows}


def timing(workers: int | None = 2) -> dict[str, Any]:
    model = build_model("classic", effects=["load_dependent_friction"],
                        params={"mu_s": 0.16, "mu_k": 0.11})
    runs = simulate_campaign(model, "force_sweep", seed=7, duration_scale=4.0 / 3.0)
    data_s = sum(r.duration_s for r in runs)
    fits: dict[str, float] = {}
    screens: list[str] = []

    def progress(msg: str) -> None:
        # "  fitted NAME: A -> B in S s [k/n ...]"; "  screened NAME: E (...)"
        m = re.match(r"  fitted (.+?): .* in (\d+) s", msg)
        if m:
            fits[m.group(1)] = float(m.group(2))
        elif msg.startswith("  screened "):
            screens.append(msg.split(":")[0].removeprefix("  screened "))

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    ds = prepare_dataset(runs)
    t1 = time.perf_counter()
    diag = diagnose(ds, ModelChoice("classic"), workers=workers, progress=progress)
    t2 = time.perf_counter()
    r0 = diag.first
    return {
        "runs": len(runs), "data_s": data_s, "samples": sum(r.n_samples for r in runs),
        "events": ds.n_events, "candidates": len(r0.ranking), "workers": workers,
        "prepare_s": t1 - t0, "diagnose_s": t2 - t1, "total_s": t2 - t0,
        "screened": len(screens), "fitted": len(fits), "full_fit_wall_s": fits,
        "verdict": r0.verdict.verdict, "loadavg_1min_before": load0,
        "loadavg_1min_after": os.getloadavg()[0],
    }


def _opt(argv: list[str], name: str) -> str | None:
    return argv[argv.index(name) + 1] if name in argv else None


def main() -> int:
    argv = sys.argv[1:]
    quick = "--quick" in argv
    as_json = "--json" in argv
    out_path = _opt(argv, "--out")
    jsonl = _opt(argv, "--jsonl")
    workers = int(_opt(argv, "--workers") or 2)
    only = [e for e in (_opt(argv, "--effects") or "").split(",") if e]
    report: dict[str, Any] = {}
    if "--matrix-only" not in argv:
        report["timing"] = t = timing(workers)
        print(f"diagnose: {t['runs']} runs, {t['data_s']:.0f} s of data, {t['events']} slips, "
              f"{t['candidates']} ranked, {workers} workers -> {t['total_s']:.1f} s wall, "
              f"{t['screened']} sets screened, {len(t['full_fit_wall_s'])} fitted fully "
              f"(verdict {t['verdict']}; load {t['loadavg_1min_before']:.1f})", flush=True)
    if "--timing-only" not in argv:
        cases = []
        done = _done(jsonl) if "--resume" in argv else set()
        for case in matrix_cases(quick, only or None, "--paired" in argv):
            if (case.effect, case.protocol, case.magnitude, case.base_set) in done:
                continue
            run_case(case, workers)
            cases.append(case)
            if jsonl:
                with open(jsonl, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps(asdict(case), default=str) + "\n")
            print(f"  {case.effect:26s} {case.protocol:17s} x{case.magnitude:<4g} "
                  f"{case.base_set:5s} -> {case.verdict:24s} red {case.reduction:5.2f} "
                  f"{'HIT' if case.hit else 'miss'} ({case.seconds:.0f} s)", flush=True)
        hits = sum(c.hit for c in cases)
        report["matrix"] = [asdict(c) for c in cases]
        report["hit_rate"] = hits / len(cases)
        print(f"hit rate {hits}/{len(cases)} = {hits / len(cases):.0%}")
    if out_path:
        with open(out_path, "w", encoding="utf-8") as fh:
            json.dump(report, fh, indent=1, default=str)
    if as_json:
        print(json.dumps(report, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
