"""The one identification search (:mod:`rigctl.workbench.search`): right on another rig's scale,
global where a local fit from off is stuck, within its budget, cancellable, with an ETA."""

from __future__ import annotations

import math
import multiprocessing
import threading
import time

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.model.noise import NoiseModel
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.budget import Budget, SearchCancelledError
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import free_params, least_squares_fit
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import default_budget, search_model, stall_generations
from rigctl.workbench.search_space import build_space

# another rig's scale: a 50 N contact on a 2e4 N/m drive, a 20 g slider (the preset: 300 N,
# 1.475e6 N/m, 48 g)
RIG = {"k0_N_per_m": 2e4, "kts_N_per_m": 1e5, "m_kg": 0.02, "mu_s": 0.4, "mu_k": 0.3,
       "mu_smax": 0.45, "kt0_N_per_m": 1.5e5, "c0_N_s_per_m": 0.4, "n_elements": 10}
FN_N = 50.0
K_EFF = 1.0 / (1.0 / RIG["k0_N_per_m"] + 1.0 / RIG["kts_N_per_m"])
DROP_N = 2.0 * (RIG["mu_s"] - RIG["mu_k"]) * FN_N
V_M_S = DROP_N / K_EFF / 3.0  # about 3 s per stick cycle
NOISE = NoiseModel(ft_rms_N=0.005 * RIG["mu_s"] * FN_N, fn_rms_N=0.002 * FN_N,
                   force_lsb_N=1e-4 * RIG["mu_s"] * FN_N, probe_rms_m=0.02 * DROP_N / K_EFF,
                   probe_lsb_m=0.005 * DROP_N / K_EFF, stage_lsb_m=0.002 * DROP_N / K_EFF)


def _campaign(protocol, effects=None, duration_scale=0.5, rate_hz=2000.0, fix=(), seed=5):
    model = build_model("paper", effects=list(effects or {}), params=RIG,
                        effect_params=effects or {})
    runs = simulate_campaign(model, protocol, seed=seed, noise=NOISE, sample_rate_hz=rate_hz,
                             fn_N=FN_N, velocity_m_s=V_M_S, duration_scale=duration_scale)
    for run in runs:  # the simulated rig states its mass and damping; also state ``fix``
        run.metadata.update({f"rig.{k}": str(RIG.get(k, 0.9)) for k in fix})
    return prepare_dataset(runs)


@pytest.fixture(scope="module")
def short():
    """A 15 s TLRE of the rig at 1 kHz: a few slips, for the budget, cancel and progress."""
    return _campaign("tlre", duration_scale=0.25, rate_hz=1000.0)


def _value(result, name):
    return result.choice.values[name]


@pytest.mark.slow
def test_it_finds_the_generating_model_of_another_rig_from_the_preset():
    dataset = _campaign("tlre")
    truth = ModelChoice("paper").with_values(RIG)
    e_truth = evaluate(dataset, truth).score.error
    res = search_model(dataset, ModelChoice("paper"), workers=2, with_uncertainty=False)
    assert not res.misses_most_slips
    assert res.error <= 1.5 * e_truth
    for name in ("mu_s", "mu_k", "mu_smax"):
        assert _value(res, name) == pytest.approx(RIG[name], rel=0.03)
    for name in ("k0_N_per_m", "kts_N_per_m"):
        assert _value(res, name) == pytest.approx(RIG[name], rel=0.15)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the search ends at a Stribeck velocity of 6.2 mm/s "
                   "(E 1.22) against 12 mm/s: a local minimum of a narrow curved valley, mu_k "
                   "following v_s within 2e-4 and the residual jumping by some 5 scatter units over "
                   "mu_k moves of 1e-4. The profile over mu_k is E 1.26, 1.23, 1.10, 1.04, 1.12 at "
                   "6, 8, 10, 12, 14 mm/s: a gain of 5.6 squared scatter units lies along the "
                   "valley, which neither CMA-ES (two coordinates, ranked through that jitter) nor "
                   "the polish (its Gauss-Newton step there is 0.05 of a resolvable step) follows. "
                   "Not the polish's trust radius (issue 34, open); strict: a search that finds it "
                   "fails this mark")
def test_it_finds_a_stribeck_velocity_from_the_effect_off():
    # velocity steps at two loads; everything but mu_k and the Stribeck velocity stated; the
    # search starts from the base fit with the effect off, where the weakening has no slope
    vs = 0.012
    fix = ("k0_N_per_m", "kts_N_per_m", "mu_s", "mu_smax", "kt0_N_per_m", "p_slope",
           "n_elements")
    dataset = _campaign("velocity_steps", {"stribeck": {"vs_m_per_s": vs}}, duration_scale=0.2,
                        rate_hz=1000.0, fix=fix, seed=7)
    off = ModelChoice("paper", ("stribeck",)).with_values(
        {**RIG, "stribeck.vs_m_per_s": 0.0, "mu_k": 0.33})
    base = least_squares_fit(dataset, off, free_params(off, ["mu_k"]), max_nfev=10)
    res = search_model(dataset, base.choice, workers=2, with_uncertainty=False)
    assert _value(res, "stribeck.vs_m_per_s") == pytest.approx(vs, rel=0.35)
    assert res.error < 0.8 * base.error


def test_the_budget_is_respected(short):
    budget = Budget(max_evaluations=40)
    res = search_model(short, ModelChoice("paper"), budget=budget, workers=2,
                       with_uncertainty=False)
    assert res.n_evaluations == budget.used <= 40
    assert math.isfinite(res.error)


def test_a_cancel_ends_the_search_and_its_workers_within_2_s(short):
    cancelled_at: list[float] = []

    def cancel_once_running(_fraction: float, _eta: float, _msg: str) -> None:
        # cancelled from another thread once the search reports progress (a timer fixed in wall
        # seconds let a quick search on an idle machine finish before it)
        if not cancelled_at:
            cancelled_at.append(time.monotonic())
            threading.Thread(target=budget.cancel).start()

    budget = Budget(max_evaluations=100_000, progress=cancel_once_running)
    with pytest.raises(SearchCancelledError):
        search_model(short, ModelChoice("paper"), budget=budget, workers=2)
    assert cancelled_at and time.monotonic() - cancelled_at[0] < 2.0
    assert not multiprocessing.active_children()


def test_progress_reports_the_fraction_done_and_an_eta(short):
    seen: list[tuple[float, float, str]] = []
    budget = Budget(max_evaluations=60)  # the search's own ``progress`` goes to its budget
    search_model(short, ModelChoice("paper"), budget=budget, workers=2, with_uncertainty=False,
                 progress=lambda f, eta, msg: seen.append((f, eta, msg)))
    etas = [eta for _, eta, _ in seen[:-1]]
    assert etas and all(math.isfinite(e) and e > 0.0 for e in etas)
    fractions = [f for f, _, _ in seen]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert seen[-1][1] == 0.0 and seen[-1][2] == "done"
    stages = [msg.split(":")[0] for _, _, msg in seen]
    assert stages.index("starts") < stages.index("local polish")  # each stage says itself
    assert any(msg.startswith("local polish: Jacobian 1 at") for _, _, msg in seen)


def test_the_search_ends_where_it_stops_gaining_inside_its_cap(short):
    budget = default_budget(9)
    res = search_model(short, ModelChoice("paper"), budget=budget, workers=2,
                       with_uncertainty=False)
    assert res.n_evaluations == budget.used < 0.6 * budget.max_evaluations
    assert "Jacobian" in res.message and "polish" in res.message
    assert not res.misses_most_slips


def test_the_effects_off_start_and_the_damping_that_follows_the_mass():
    model = build_model("paper", params=RIG)
    runs = simulate_campaign(model, "tlre", seed=5, noise=NOISE, sample_rate_hz=1000.0, fn_N=FN_N,
                             velocity_m_s=V_M_S, duration_scale=0.25)
    for run in runs:  # another rig's record: mass and damping not stated
        for name in ("m_kg", "c0_N_s_per_m"):
            run.metadata.pop(f"rig.{name}", None)
    dataset = prepare_dataset(runs)
    choice = ModelChoice("paper", ("stribeck",))
    space = build_space(dataset, choice, choice, spreads_elements=False)
    names = [fp.name for fp in space.free]
    i_vs, i_m, i_c = (names.index(n) for n in ("stribeck.vs_m_per_s", "m_kg", "c0_N_s_per_m"))
    assert space.off[i_vs] == pytest.approx(space.free[i_vs].to_u(0.0))  # linear: off is 0
    assert space.follows == {i_c: (i_m, 0.5)}
    x0 = space.vector(choice)
    x = space.spread_point(x0, {i_m: x0[i_m] + math.log(100.0)})  # 100 times the mass
    assert math.exp(x[i_c] - x0[i_c]) == pytest.approx(10.0)  # C0 with sqrt(M): same ratio
    cov = space.prior_cov()
    assert cov[i_c, i_m] == pytest.approx(0.5 * space.std[i_m] ** 2)
    assert np.all(np.linalg.eigvalsh(cov) > 0.0)


def test_stall_generations_is_the_step_size_paths_horizon():
    # 1 / c_sigma with c_sigma = (mu_eff + 2) / (n + mu_eff + 5) (Hansen 2016, eq. 55)
    assert stall_generations(9, 2.9) == 4
    assert stall_generations(40, 5.0) == 8


def test_a_wall_limit_ends_the_search_near_it_with_its_best_point(short):
    free = search_model(short, ModelChoice("paper"), workers=2, with_uncertainty=False)
    limit_s = 0.4 * free.elapsed_s  # the search alone would take 2.5 times longer
    res = search_model(short, ModelChoice("paper"), workers=2, with_uncertainty=False,
                       max_wall_s=limit_s)
    assert math.isfinite(res.error) and not res.misses_most_slips
    assert res.n_evaluations < free.n_evaluations
    # within the limit and one last batch (an evaluation here takes a fraction of a second)
    assert res.elapsed_s < limit_s + 3.0
    assert "polish" in res.message
    assert res.time_limited and not free.time_limited


def test_a_wall_limit_must_be_positive(short):
    with pytest.raises(ValueError, match="max_wall_s"):
        search_model(short, ModelChoice("paper"), workers=0, max_wall_s=0.0)
    with pytest.raises(ValueError, match="budget"):  # a given budget carries its own limit
        search_model(short, ModelChoice("paper"), workers=0, max_wall_s=10.0,
                     budget=Budget(max_evaluations=10))
