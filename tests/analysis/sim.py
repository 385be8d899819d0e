"""Simulated runs with a known truth for the analysis tests (the model itself, with sensor noise)."""

from __future__ import annotations

import functools

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.model import Drive, SimResult, Simulator, build_model
from rigctl.model.noise import NoiseModel

FN_N = 300.0
V_M_S = 1e-5


@functools.lru_cache(maxsize=8)
def one_pass(fn_N: float = FN_N, duration_s: float = 60.0, seed: int = 1,
             effects: tuple[str, ...] = ()) -> tuple[SimResult, MeasuredRun]:
    """2 s at rest, then a slide at 10 um/s: one initial stage and about a dozen stable cycles."""
    model = build_model("paper", effects=list(effects))
    res = Simulator(model).run(Drive.segments(fn_N=fn_N, segments=[(2.0, 0.0),
                                                                  (duration_s, V_M_S)]))
    NoiseModel().apply(res, np.random.default_rng(seed))
    run = res.to_measured()
    run.source = f"sim_{fn_N:.0f}N.csv"
    return res, run


@functools.lru_cache(maxsize=2)
def two_passes(seed: int = 2) -> tuple[SimResult, MeasuredRun]:
    """A TLRE in miniature: load, rest, slide, release, return, load, rest, slide, release."""
    t: list[float] = [0.0]
    x: list[float] = [0.0]
    fn: list[float] = [0.0]

    def seg(dur: float, x_end: float, fn_end: float) -> None:
        t.append(t[-1] + dur)
        x.append(x_end)
        fn.append(fn_end)

    for _ in range(2):
        seg(1.0, 0.0, FN_N)               # load
        seg(2.0, 0.0, FN_N)               # settle
        seg(30.0, 3e-4, FN_N)             # slide 300 um at 10 um/s
        seg(0.5, 3e-4, 0.0)               # release
        seg(1.0, 3e-4, 0.0)
        seg(6.0, 0.0, 0.0)                # return at 50 um/s
        seg(1.0, 0.0, 0.0)                # rest, apart
    model = build_model("paper")
    res = Simulator(model).run(Drive(np.array(t), np.array(x), np.array(fn)))
    NoiseModel().apply(res, np.random.default_rng(seed))
    run = res.to_measured()
    run.source = "sim_two_passes.csv"
    return res, run


def settled_trough_N(trough_N: float, fn_N: float) -> float:
    """The drive force the model settles at after a stable slip (its exact equilibrium).

    A slip ends (V = 0) with the drive force at its trough F_e and the elements re-sticking with
    their kinetic force mu_k Fn (docs/model.md, section 2). The specimen then rings about the
    equilibrium of the drive spring K0 and the stuck interface Kts, which it reaches after moving
    by (F_e - mu_k Fn) / (K0 + Kts): the drive force there is F_e + K0 (mu_k Fn - F_e) / (K0 + Kts).
    """
    params = build_model("paper").base_values
    k0, kts, mu_k = params["k0_N_per_m"], params["kts_N_per_m"], params["mu_k"]
    return trough_N + k0 * (mu_k * fn_N - trough_N) / (k0 + kts)
