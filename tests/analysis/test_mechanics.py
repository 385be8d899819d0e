"""The mechanical analyses recover what the model produced (simulated runs with sensor noise)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.analysis.friction import friction_coefficients
from rigctl.analysis.mechanics import analyse_mechanics
from rigctl.analysis.passes import find_passes
from rigctl.analysis.stickslip import read_pass
from rigctl.analysis.stiffness import cycle_stiffness
from rigctl.model import build_model
from tests.analysis.sim import FN_N, one_pass, settled_trough_N, two_passes

KTS = build_model("paper").base_values["kts_N_per_m"]


@pytest.fixture(scope="module")
def single():
    res, run = one_pass()
    passes = find_passes(run)
    assert len(passes) == 1
    rec = read_pass(run, passes[0])
    return res, rec


def test_one_pass_from_rest(single):
    res, rec = single
    assert rec.has_initial
    assert rec.cycles.stage[0] == "initial"
    assert all(s == "stable" for s in rec.cycles.stage[1:])
    # every slip of the model is found, at its time
    assert rec.cycles.n == len(res.events)
    t_model = np.array([e.t_start_s for e in res.events])
    assert np.max(np.abs(rec.cycles.t_peak_s - t_model)) < 0.01
    assert abs(rec.pas.t_motion_s - 2.0) < 0.01


def test_friction_coefficients_within_2_percent_of_the_model(single):
    res, rec = single
    fc = friction_coefficients(rec)
    ev = res.events
    stable = [e for e in ev if e.stage == "stable"]
    mu_s_max = ev[0].peak_N / FN_N
    mu_s = np.mean([e.peak_N for e in stable]) / FN_N
    # mu_k: the paper's minimum of Ft in the stable stage, the level the drive force settles at
    mu_k = np.mean([settled_trough_N(e.trough_N, FN_N) for e in stable]) / FN_N
    assert fc.mu_s_max == pytest.approx(mu_s_max, rel=0.02)
    assert fc.mu_s.mean == pytest.approx(mu_s, rel=0.02)
    assert fc.mu_k.mean == pytest.approx(mu_k, rel=0.02)
    # one value per stable cycle, and a spread far below the values (the model repeats exactly)
    assert fc.mu_s.n >= len(stable) - 1
    assert 0 < fc.mu_s.std < 0.01 * fc.mu_s.mean


def test_stable_k_within_5_percent_of_the_interface_stiffness(single):
    _, rec = single
    stiff = cycle_stiffness(rec)
    k = np.array([s.k.k_N_per_m for s in stiff])
    stable = k[rec.stable]
    assert np.isfinite(stable).sum() >= 8
    assert np.all(np.abs(stable[np.isfinite(stable)] / KTS - 1.0) < 0.05)
    # K(1) of the initial stage is larger (Kt0 > Kts; paper Fig. 6d)
    assert k[0] > 1.3 * np.nanmean(stable)
    assert all(np.isfinite(s.k.se_N_per_m) and s.k.se_N_per_m < 0.02 * KTS for s in stiff[1:])


def test_initial_k_i_falls_and_stable_k_i_is_flat(single):
    _, rec = single
    stiff = cycle_stiffness(rec)
    k_init = np.array([b.k_N_per_m for b in stiff[0].k_inst])
    assert np.isfinite(k_init).all()
    assert k_init[0] > 2.0 * k_init[-1]
    # falling all along (the back-end elements slip one after another)
    rho = np.corrcoef(np.arange(k_init.size), k_init)[0, 1]
    assert rho < -0.9
    for s in stiff[2:6]:
        k_st = np.array([b.k_N_per_m for b in s.k_inst])
        assert np.isfinite(k_st).all()
        assert k_st.max() / k_st.min() < 1.05


def test_two_passes_each_with_its_initial_stage_and_repeatability():
    _res, run = two_passes()
    mech = analyse_mechanics(run)
    assert len(mech.passes) == 2
    assert all(r.has_initial for r in mech.passes)
    for fc in mech.friction:
        assert fc.mu_s_max == pytest.approx(0.2, rel=0.02)
    rep = {r.name: r for r in mech.repeatability}
    assert len(rep["max Ft"].values) == 2
    assert rep["max Ft"].relative_error < 0.01
    assert not any("not analysed" in n for n in mech.notes)


def test_a_run_without_tangential_motion_says_so():
    _, run = one_pass()
    still = type(run)(run.t_s, np.zeros_like(run.t_s), run.fn_N, run.ft_N, run.d1_m, run.d2_m,
                      source="still.csv")
    mech = analyse_mechanics(still)
    assert mech.passes == []
    assert any("no tangential pass" in n for n in mech.notes)
