"""Benchmark of one model evaluation (rigctl/workbench/evaluate.py): where its time goes.

One evaluation simulates the model on every run of a campaign and reads the model's slips and
features from the sampled series as the measurement's are read, then scores them. A fit makes
hundreds of them. The campaign is issue 34's: another rig (a 50 g slider on a 20 kN/m drive at 20 N,
20 interface elements), six runs at 2 kHz with sensor noise: a force sweep at three loads (60 s
each), velocity steps at two loads, a slide-hold-slide (464 s of record, 928,000 samples).

Measured side by side in one process, alternating, median of the repeats (docs/performance.md,
"Evaluation"):

* the integration (``simulate_run`` over the six runs);
* reading the model's series by the compiled reader (``rigctl.records``: slip scan and window
  reads in numba) and by the Python reader it replaced (tests/records/reference_events.py, kept as
  the test oracle), on the same simulated series;
* the score;

at two models: the generating one (a fit's end) and one far from the data (a fit's start: a lighter
slider with a higher kinetic friction, whose ringing passes the threshold again and again).
``--quick``: 3 repeats instead of 9.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from typing import Any

import numpy as np

from rigctl.model import ModelSpec, build_model
from rigctl.model.noise import NoiseModel
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.records.features import extract_events
from rigctl.workbench.campaigns import protocol_runs, simulate_campaign
from rigctl.workbench.evaluate import simulate_run
from rigctl.workbench.metrics import score

RIG = dict(k0_N_per_m=2.0e4, kts_N_per_m=8e4, m_kg=0.05, mu_s=0.45, mu_k=0.36, mu_smax=0.5,
           kt0_N_per_m=1.2e5, c0_N_s_per_m=2 * 0.01 * (2e4 * 0.05) ** 0.5, n_elements=20)
FAR = {**RIG, "m_kg": 0.02, "mu_k": 0.40}
FN_N = 20.0
RATE_HZ = 2000.0


def _velocity() -> float:
    """A drive speed giving sticks of about a third of a second at FN_N."""
    keff = 1.0 / (1.0 / RIG["k0_N_per_m"] + 1.0 / RIG["kts_N_per_m"])
    return 2.0 * (RIG["mu_s"] - RIG["mu_k"]) * FN_N / keff / 3.0


def campaign() -> Dataset:
    """The six runs, read as measured records."""
    model = build_model("paper", params=RIG)
    scale = 2.0 * (RIG["mu_s"] - RIG["mu_k"]) * FN_N / 2.0e4
    noise = NoiseModel(ft_rms_N=0.005 * RIG["mu_s"] * FN_N, fn_rms_N=0.002 * FN_N,
                       force_lsb_N=1e-4 * RIG["mu_s"] * FN_N, probe_rms_m=0.02 * scale,
                       probe_lsb_m=0.005 * scale, stage_lsb_m=0.002 * scale)
    v = _velocity()
    runs = []
    for j, f in enumerate((0.6, 1.0, 1.6)):
        runs += simulate_campaign(model, "tlre", seed=j, noise=noise, sample_rate_hz=RATE_HZ,
                                  fn_N=FN_N * f, velocity_m_s=v)
    runs += simulate_campaign(model, "velocity_steps", seed=10, noise=noise,
                              sample_rate_hz=RATE_HZ, fn_N=FN_N, velocity_m_s=v)
    runs += simulate_campaign(model, "slide_hold_slide", seed=20, noise=noise,
                              sample_rate_hz=RATE_HZ, fn_N=FN_N, velocity_m_s=v)
    assert len(runs) == 3 + len(protocol_runs("velocity_steps")) + 1
    for run in runs:  # another lab's records state no mass or damping
        for key in [k for k in run.metadata if k.startswith("rig.")]:
            del run.metadata[key]
    return prepare_dataset(runs)


def _time_evaluation(ds: Dataset, spec: ModelSpec, repeats: int) -> dict[str, Any]:
    from tests.records import reference_events

    def read(fn: Any, results: list[Any]) -> tuple[float, list[Any]]:
        t0 = time.perf_counter()
        events = [fn(r.t_s, r.ft_N, r.d1_m - r.d2_m, r.fn_N, run.drive, run.read)
                  for r, run in zip(results, ds.runs, strict=True)]
        return time.perf_counter() - t0, events

    sims: list[float] = []
    news: list[float] = []
    olds: list[float] = []
    scores: list[float] = []
    n_slips = 0
    for k in range(repeats + 1):  # the first is a warm-up (numba's cache load, page faults)
        t0 = time.perf_counter()
        results = [simulate_run(spec, run, bounded=True) for run in ds.runs]
        t_sim = time.perf_counter() - t0
        readers = [(news, extract_events), (olds, reference_events.extract_events)]
        for store, fn in (readers if k % 2 else readers[::-1]):
            t_read, events = read(fn, results)
            if k:
                store.append(t_read)
        t0 = time.perf_counter()
        score(ds, events)
        t_score = time.perf_counter() - t0
        if k:
            sims.append(t_sim)
            scores.append(t_score)
        n_slips = sum(e.n for e in events)
    sim, new, old, sc = (statistics.median(x) for x in (sims, news, olds, scores))
    return {
        "model_slips": n_slips,
        "integration_s": sim, "read_compiled_s": new, "read_python_s": old, "score_s": sc,
        "evaluation_before_s": sim + old + sc, "evaluation_now_s": sim + new + sc,
        "integrator_share_before": sim / (sim + old + sc),
        "integrator_share_now": sim / (sim + new + sc),
        "speedup": (sim + old + sc) / (sim + new + sc),
        "read_speedup": old / new,
    }


def evaluation_benchmark(quick: bool = False) -> dict[str, Any]:
    t0 = time.perf_counter()
    ds = campaign()
    t_prep = time.perf_counter() - t0
    repeats = 3 if quick else 9
    load0 = os.getloadavg()[0]
    out: dict[str, Any] = {
        "campaign": {"runs": len(ds.runs), "samples": int(sum(r.n_samples for r in ds.runs)),
                     "record_s": float(sum(r.n_samples for r in ds.runs)) / RATE_HZ,
                     "measured_slips": ds.n_events, "prepare_s": t_prep},
        "near": _time_evaluation(ds, build_model("paper", params=RIG), repeats),
        "far": _time_evaluation(ds, build_model("paper", params=FAR), max(3, repeats // 3)),
    }
    out["machine"] = {"cpu_count": os.cpu_count(), "loadavg_1min_start": load0,
                      "loadavg_1min_end": os.getloadavg()[0]}
    return out


def format_table(r: dict[str, Any]) -> str:
    c = r["campaign"]
    lines = [f"campaign: {c['runs']} runs, {c['record_s']:.0f} s at 2 kHz, "
             f"{c['measured_slips']} measured slips",
             f"{'model':<6} {'slips':>6} {'integrate':>10} {'read py':>9} {'read nb':>9} "
             f"{'score':>7} {'eval before':>12} {'eval now':>9} {'ratio':>6} {'int. share':>16}"]
    for name in ("near", "far"):
        m = r[name]
        lines.append(
            f"{name:<6} {m['model_slips']:>6} {m['integration_s']:>9.3f}s "
            f"{m['read_python_s']:>8.3f}s {m['read_compiled_s']:>8.3f}s {m['score_s']:>6.3f}s "
            f"{m['evaluation_before_s']:>11.3f}s {m['evaluation_now_s']:>8.3f}s "
            f"{m['speedup']:>5.1f}x {m['integrator_share_before']:>6.0%} -> "
            f"{m['integrator_share_now']:.0%}")
    mc = r["machine"]
    lines.append(f"machine: {mc['cpu_count']} cores, load {mc['loadavg_1min_start']:.1f} -> "
                 f"{mc['loadavg_1min_end']:.1f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.bench_evaluation [--quick] [--json]``."""
    args = sys.argv[1:] if argv is None else argv
    res = evaluation_benchmark(quick="--quick" in args)
    print(json.dumps(res, indent=2) if "--json" in args else format_table(res))
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
