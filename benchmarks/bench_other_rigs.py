"""Held-out rigs: ``diagnose --auto`` on campaigns of rigs that are not this one.

``python -m benchmarks.bench_other_rigs [--cases N] [--first I] [--seed S] [--workers N] [--jsonl FILE]
[--case-limit-s S]``

Each case is a rig drawn at random, far from this rig's preset: normal force 0.5 N to 5 kN, drive
stiffness 1e2 to 1e7 N/m, interface 0.5 to 20 times stiffer, mass 1 g to 1 kg, friction 0.1 to 0.8
with a 5 to 40 % static-kinetic gap, 5 to 40 interface elements, sampling at 500 Hz to 5 kHz and
noise at 0.5 % of the force (sensor) and 2 % of the slip distance (probes) times a factor of 0.5
to 3. A rig whose tlre campaign shows fewer than MIN_EVENTS slips is drawn again (no stick-slip to
compare). Its campaign runs the protocols that
reveal the hidden effects (tlre always; velocity steps, slide-hold-slide or a force sweep at 0.6
to 1.6 times the rig's own load where the effects need them) at a drive velocity that gives about
3 s per stick cycle. A case hides nothing (control), two effects, one, or two (cycling in that
order), each at its typical magnitude (default minus off value, ``scales_with`` quantities carried
to the rig: the same rule the workbench uses for its starting values, applied here to make the
truth, with the magnitude drawn in [0.7, 1.5]), its shape parameters drawn within a factor
SHAPE_FACTOR of their typical values.

A case is a **hit** when ``--auto`` adds exactly the hidden effects (either order) and ends at most
at half the baseline error (a control: adds nothing); else **indistinguishable** when it stopped
because the data cannot decide between sets (``truth_among_undecided``: one of them completes the
hidden set), else **wrong**. With ``--case-limit-s``, a case whose diagnosis is still running at
that many wall seconds is cancelled (as the GUI's Cancel does) and answers **time limit**: a miss
with no name, its time the limit. Each case also gives ``truth_error``, what the generating model
itself scores on the case's data (the floor a fit is judged against), and the peak resident
memory so far of this process and of its largest finished worker (``peak_rss_mb``, from
``getrusage``: maxima over the run, so a case's figure includes the cases before it). Figures are
printed per case and summed; nothing asserts a time.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rigctl.data import DataError
from rigctl.errors import SimulationError
from rigctl.model import Drive, ParameterError, Simulator, build_model
from rigctl.model.effects import LIBRARY
from rigctl.model.noise import NoiseModel
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.auto_diagnosis import diagnose_auto
from rigctl.workbench.budget import SearchCancelledError
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, simulate_campaign
from rigctl.workbench.data_scale import DataScale, scale_ratios
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.ranking import VerdictKind

HIDEABLE = tuple(e for e in LIBRARY
                 if e not in ("stress_evolution", "probe_drift", "interface_damping"))
"""Effects hidden in cases. Not: stress_evolution (part of the paper base); probe_drift (needs
probes this generator does not model at a realistic resolution); interface_damping (on another
rig's data the drive damping C0 is fitted, and a damper between mass and ground is then the same
physics as one in the drive path, up to C0 v_stage: the data cannot tell them apart)."""
SAMPLE_RATE_HZ = 2000.0
"""The rate effect magnitudes are scaled at (a case samples at its own rate)."""
RATE_RANGE_HZ = (500.0, 5000.0)
ELEMENTS_RANGE = (5, 40)
NOISE_FACTOR_RANGE = (0.5, 3.0)
MIN_EVENTS = 10
HIDDEN_PATTERN = (0, 2, 1, 2)
"""Hidden effects per case, cycling: the two-effect cases are the hard ones."""


def draw_rig(rng: np.random.Generator) -> dict[str, float]:
    fn = float(10 ** rng.uniform(math.log10(0.5), math.log10(5000.0)))
    k0 = float(10 ** rng.uniform(2.0, 7.0))
    kts = k0 * float(10 ** rng.uniform(math.log10(0.5), math.log10(20.0)))
    m = float(10 ** rng.uniform(-3.0, 0.0))
    mu_s = float(rng.uniform(0.1, 0.8))
    mu_k = mu_s * (1.0 - float(rng.uniform(0.05, 0.4)))
    zeta = 0.01
    return {"fn_N": fn, "k0_N_per_m": k0, "kts_N_per_m": kts, "m_kg": m, "mu_s": mu_s,
            "mu_k": mu_k, "mu_smax": mu_s * float(rng.uniform(1.0, 1.3)),
            "kt0_N_per_m": kts * float(rng.uniform(1.0, 2.0)),
            "c0_N_s_per_m": 2.0 * zeta * math.sqrt(k0 * m),
            "n_elements": int(rng.integers(ELEMENTS_RANGE[0], ELEMENTS_RANGE[1] + 1))}


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(10 ** rng.uniform(math.log10(lo), math.log10(hi)))


def _scale_of(rig: dict[str, float], v: float) -> DataScale:
    keff = 1.0 / (1.0 / rig["k0_N_per_m"] + 1.0 / rig["kts_N_per_m"])
    drop = 2.0 * (rig["mu_s"] - rig["mu_k"]) * rig["fn_N"]
    return DataScale(fn_N=rig["fn_N"], v_m_per_s=v, mu_peak=rig["mu_s"],
                     mu_trough=2.0 * rig["mu_k"] - rig["mu_s"], mu_first=math.nan,
                     k_eff_N_per_m=keff, k_stick_N_per_m=rig["kts_N_per_m"],
                     stick_s=drop / keff / v)


SHAPE_FACTOR = 2.0
"""A shape parameter of a hidden effect (one whose off value is its library default: it switches
nothing on, it shapes what the others switch on, a Stribeck exponent, a characteristic slip
distance, a wear length) is drawn log-uniformly within this factor of its typical value at the
rig's scale: other labs' laws have other shapes (Stribeck exponents 0.5 to 2, Armstrong-Helouvry
et al. 1994), which the workbench must represent, not assume."""


def hidden_values(effect: str, rig: dict[str, float], v: float, magnitude: float,
                  rng: np.random.Generator) -> dict[str, float]:
    eff = LIBRARY[effect]()
    offs = eff.off_values({"mu_s": rig["mu_s"], "kts_N_per_m": rig["kts_N_per_m"]})
    ratios = scale_ratios(_scale_of(rig, v), rig, SAMPLE_RATE_HZ)
    out = {}
    for p in eff.params:
        default = p.default
        if p.scales_with and math.isfinite(ratios.get(p.scales_with, math.nan)):
            default = p.default * ratios[p.scales_with]
        if not p.identify:
            value = default
        elif p.off == p.default:  # a shape parameter
            value = default * SHAPE_FACTOR ** float(rng.uniform(-1.0, 1.0))
        else:
            value = offs[p.name] + magnitude * (default - offs[p.name])
        out[p.name] = float(min(max(value, p.lower), p.upper))
    return out


SWEEP_FACTORS = (0.6, 0.8, 1.0, 1.3, 1.6)
"""A force sweep of another rig spans its own load (the library's sweep steps this rig's 50 N)."""


def _sweep(model: Any, fn_N: float, v: float, noise: NoiseModel | bool, seed: int,
           rate_hz: float) -> list[Any]:
    sim = Simulator(model, sample_rate_hz=rate_hz)
    out = []
    for j, f in enumerate(SWEEP_FACTORS):
        res = sim.run(Drive.constant(fn_N * f, v, 30.0), noise=noise, seed=seed * 1000 + j,
                      record_elements=False)
        run = res.to_measured()
        run.source = f"sweep_{fn_N * f:.3g}N"
        out.append(run)
    return out


def draw_case(i: int, seed: int, pattern: tuple[int, ...] = HIDDEN_PATTERN, *,
              noisy: bool = True,
              ) -> tuple[list[Any], tuple[str, ...], ModelChoice, dict[str, Any]]:
    """Case ``i`` of ``seed``: its runs, the hidden effects, the generating model and how it was
    drawn (rig, rate, noise factor, protocols). A case depends only on ``seed``, ``i`` and the
    hidden-effect counts ``pattern`` cycles through. ``noisy=False``: the same case's noise-free
    twin (the same rig, effects, drives and physics; no sensor noise or quantisation), for
    reading the same series with and without the record's noise (``benchmarks.reading_noise``)."""
    rng = np.random.default_rng(seed * 7919 + i)
    n_hidden = pattern[i % len(pattern)]
    hidden = tuple(str(e) for e in rng.choice(HIDEABLE, size=n_hidden, replace=False))
    for _attempt in range(20):
        rig = draw_rig(rng)
        rate_hz = _log_uniform(rng, *RATE_RANGE_HZ)
        noise_factor = _log_uniform(rng, *NOISE_FACTOR_RANGE)
        state = rng.bit_generator.state  # the campaign's own draws, for its noise-free twin
        runs, protocols, truth = _campaign(rng, rig, hidden, rate_hz, noise_factor, seed)
        try:
            tlre = prepare_dataset([r for r in runs if r.source.startswith("tlre")])
        except DataError:  # no slip at all
            continue
        if tlre.n_events >= MIN_EVENTS:
            break
    else:
        raise RuntimeError(f"case {i}: no rig with stick-slip in 20 draws")
    if not noisy:  # the rig the noisy case accepted, its campaign drawn again without noise
        rng.bit_generator.state = state
        runs, protocols, truth = _campaign(rng, rig, hidden, rate_hz, noise_factor, seed,
                                           noisy=False)
    drawn = {"rate_hz": round(rate_hz), "noise_factor": round(noise_factor, 2),
             "rig": {k: float(f"{val:.3g}") for k, val in rig.items()}, "protocols": protocols}
    return runs, hidden, truth, drawn


def run_case(i: int, seed: int, workers: int, verbose: bool = False,
             limit_s: float | None = None) -> dict[str, Any]:
    runs, hidden, truth, drawn = draw_case(i, seed)
    t0 = time.perf_counter()
    ds = prepare_dataset(runs)
    say = (lambda msg: print(f"[case {i}] {msg}", file=sys.stderr, flush=True)) if verbose else None
    cancel = threading.Event()
    timer = threading.Timer(limit_s, cancel.set) if limit_s else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        diag = diagnose_auto(ds, ModelChoice("paper"), workers=workers, progress=say,
                             cancel=cancel)
    except SearchCancelledError:
        diag = None
    finally:
        if timer is not None:
            timer.cancel()
    wall = time.perf_counter() - t0
    try:  # what the generating model itself scores: the floor a fit can be judged against
        truth_err = float(evaluate(ds, truth).score.error)
    except (SimulationError, ParameterError):
        truth_err = math.nan
    if diag is None:
        return {"case": i, "hidden": list(hidden), "final": [], "added": [],
                "answer": "time limit", "undecided_between": [], "truth_among_undecided": False,
                "rate_hz": drawn["rate_hz"], "noise_factor": drawn["noise_factor"],
                "removed": [], "baseline_error": math.nan, "final_error": math.nan,
                "hit": False, "wall_s": wall, "n_events": ds.n_events, "truth_error": truth_err,
                "unexplained": f"cancelled at the case time limit ({limit_s:.0f} s)",
                "rig": drawn["rig"], "protocols": drawn["protocols"]}
    added = [st.added for st in diag.steps if st.added]
    removed = [st.note for st in diag.steps if st.note.startswith("removed")]
    final = [e for e in diag.final_model.choice.effects]
    base_err, final_err = diag.steps[0].error, diag.final_model.error
    hit = sorted(final) == sorted(hidden) and (not hidden or final_err <= 0.5 * base_err)
    last = diag.rounds[-1].verdict
    undecided = last.kind is VerdictKind.INDISTINGUISHABLE
    # an undecided answer is right to be undecided when a contender, added to the final model,
    # would make exactly the hidden set
    fair = undecided and any(sorted({*final, *c.split(" + ")}) == sorted(hidden)
                             for c in last.candidates)
    answer = "hit" if hit else ("indistinguishable" if undecided else "wrong")
    return {"case": i, "hidden": list(hidden), "final": final, "added": added,
            "answer": answer, "undecided_between": last.candidates if undecided else [],
            "truth_among_undecided": fair,
            "rate_hz": drawn["rate_hz"], "noise_factor": drawn["noise_factor"],
            "removed": removed, "baseline_error": base_err, "final_error": final_err,
            "hit": hit, "wall_s": wall, "n_events": ds.n_events, "truth_error": truth_err,
            "unexplained": diag.rounds[-1].verdict.unexplained,
            "run_time_limited": diag.time_limited,
            "rig": drawn["rig"], "protocols": drawn["protocols"]}


def peak_rss_mb() -> dict[str, float]:
    """Peak resident memory so far (MB) of this process and of its largest terminated child (the
    search's worker processes end with each pool)."""
    to_mb = 1024.0 if sys.platform.startswith("linux") else 1024.0 * 1024.0  # KB on Linux
    return {"parent": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / to_mb, 1),
            "largest_worker": round(
                resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / to_mb, 1)}


def run_cases(run: Callable[[int], dict[str, Any]], first: int, cases: int,
              jsonl: str) -> list[dict[str, Any]]:
    """``run`` of each case index from ``first``: each result printed as a JSON line as it ends
    (and appended to ``jsonl`` where given), all of them returned."""
    results = []
    for i in range(first, first + cases):
        res = {**run(i), "peak_rss_mb": peak_rss_mb()}
        results.append(res)
        line = json.dumps(res)
        print(line, flush=True)
        if jsonl:
            with open(jsonl, "a", encoding="utf-8") as fh:
                fh.write(line + "\n")
    return results


def _campaign(rng: np.random.Generator, rig: dict[str, float], hidden: tuple[str, ...],
              rate_hz: float, noise_factor: float, seed: int, noisy: bool = True,
              ) -> tuple[list[Any], list[str], ModelChoice]:
    keff = 1.0 / (1.0 / rig["k0_N_per_m"] + 1.0 / rig["kts_N_per_m"])
    drop = 2.0 * (rig["mu_s"] - rig["mu_k"]) * rig["fn_N"]
    v = drop / keff / 3.0  # about 3 s per stick cycle
    values = {e: hidden_values(e, rig, v, float(rng.uniform(0.7, 1.5)), rng) for e in hidden}
    params = {k: val for k, val in rig.items() if k != "fn_N"}
    model = build_model("paper", effects=list(hidden), params=params, effect_params=values)
    f = noise_factor
    noise: NoiseModel | bool = NoiseModel(
        ft_rms_N=f * 0.005 * rig["mu_s"] * rig["fn_N"], fn_rms_N=f * 0.002 * rig["fn_N"],
        force_lsb_N=1e-4 * rig["mu_s"] * rig["fn_N"], probe_rms_m=f * 0.02 * drop / keff,
        probe_lsb_m=0.005 * drop / keff, stage_lsb_m=0.002 * drop / keff) if noisy else False
    protocols = ["tlre", *sorted({PROTOCOL_FOR_EFFECT[e] for e in hidden} - {"tlre"})]
    runs: list[Any] = []
    for k, proto in enumerate(protocols):
        if proto == "force_sweep":
            runs += _sweep(model, rig["fn_N"], v, noise, seed * 100 + k, rate_hz)
            continue
        runs += simulate_campaign(model, proto, seed=seed * 100 + k, noise=noise,
                                  sample_rate_hz=rate_hz, fn_N=rig["fn_N"],
                                  velocity_m_s=v, duration_scale=1.0)
    for run in runs:  # another lab's record: it does not state the generating rig's mass and damping
        for key in [k for k in run.metadata if k.startswith("rig.")]:
            del run.metadata[key]
    truth = ModelChoice("paper", hidden)
    names = {p.name for p in truth.parameter_table()}
    given = {**params, **{f"{e}.{k}": val for e, vals in values.items() for k, val in vals.items()}}
    return runs, protocols, truth.with_values({k: v for k, v in given.items() if k in names})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=8)
    ap.add_argument("--first", type=int, default=0,
                    help="first case index (a case depends only on --seed and its index)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--jsonl", default="")
    ap.add_argument("--verbose", action="store_true",
                    help="the diagnosis's progress (each candidate's fit, each step) on stderr")
    ap.add_argument("--case-limit-s", type=float, default=0.0,
                    help="cancel a case's diagnosis after this many wall seconds and count it "
                         "as a miss (default: no limit)")
    args = ap.parse_args(argv)
    if args.case_limit_s < 0:
        ap.error("--case-limit-s must not be negative")
    results = run_cases(lambda i: run_case(i, args.seed, args.workers, args.verbose,
                                           args.case_limit_s or None),
                        args.first, args.cases, args.jsonl)
    hits = sum(r["hit"] for r in results)
    undecided = sum(r["answer"] == "indistinguishable" for r in results)
    stopped = sum(r["answer"] == "time limit" for r in results)
    print(f"hits {hits}/{len(results)}, indistinguishable {undecided}, stopped at the time limit "
          f"{stopped}, wrong {len(results) - hits - undecided - stopped}; "
          f"wall {sum(r['wall_s'] for r in results):.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
