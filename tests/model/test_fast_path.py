"""The fast stick recurrence (rigctl/model/kernel/fast_stick.py) with the effects whose state it
carries: sensor_dynamics, normal_coupling and rate_state aging. It must carry most samples, and agree
with the general exact step to round-off."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import SimResult, Simulator, build_model, layout

FN = 300.0
V = 1e-4
DURATION_S = 6.0
EFFECTS = [["sensor_dynamics"], ["normal_coupling"], ["rate_state"],
           ["normal_coupling", "sensor_dynamics"], ["rate_state", "sensor_dynamics"],
           ["rate_state", "normal_coupling"]]


def _run(effects: list[str], fn_end_N: float) -> tuple[SimResult, int]:
    """A 6 s slide at constant velocity; Fn goes linearly from FN to fn_end_N."""
    sim = Simulator(build_model("paper", effects=effects))
    step = sim.stepper(0.0, FN)
    res = step.advance(DURATION_S, V * DURATION_S, fn_end_N)
    return res, int(step._integ.ist[layout.I_FAST])


@pytest.mark.parametrize("effects", EFFECTS, ids="+".join)
def test_fast_path_carries_the_stick_phases(effects):
    res, n_fast = _run(effects, FN)
    assert len(res.events) >= 5
    # all but the initial stage (presliding elements), the slips and a few samples around each
    n_initial = int(np.sum(res.stage == 0))
    assert n_fast >= 0.8 * (res.t_s.size - n_initial), (n_fast, res.t_s.size, n_initial)


@pytest.mark.parametrize("effects", EFFECTS, ids="+".join)
def test_fast_path_agrees_with_the_general_step(effects):
    fast, n_fast = _run(effects, FN)
    # a normal force that rises by 1 nN over the run keeps every step on the general exact step
    # (the fast path needs constant inputs) and changes the physics by ~3e-12 relative
    general, n_general = _run(effects, FN + 1e-9)
    assert n_general == 0 and n_fast > 0
    assert len(fast.events) == len(general.events)
    for a, b in zip(fast.events, general.events, strict=True):
        assert abs(a.t_start_s - b.t_start_s) < 1e-9
        assert abs(a.peak_N - b.peak_N) < 1e-6 and abs(a.trough_N - b.trough_N) < 1e-6
    for col in ("ft_N", "fn_N", "f_interface_N"):
        np.testing.assert_allclose(getattr(fast, col), getattr(general, col), rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.x_specimen_m, general.x_specimen_m, rtol=0, atol=1e-12)


def test_fast_path_follows_presliding_elements_under_aging():
    """The paper base's initial stage at 10 um/s: elements preslide one by one while rate_state ages
    them; the fast path rebuilds its particular solution per sample and agrees with the general
    step."""
    runs = []
    for fn_end in (FN, FN + 1e-9):
        sim = Simulator(build_model("paper", effects=["rate_state"]))
        step = sim.stepper(0.0, FN)
        res = step.advance(4.5, 4.5e-5, fn_end)
        runs.append((res, int(step._integ.ist[layout.I_FAST])))
    (fast, n_fast), (general, n_general) = runs
    presliding = (fast.element_mode != 0).any(axis=1) & (fast.stage == 0) & ~fast.slipping
    assert presliding.sum() > 1000 and n_general == 0
    assert n_fast > 0.9 * fast.t_s.size
    assert len(fast.events) == len(general.events)
    np.testing.assert_allclose(fast.ft_N, general.ft_N, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.f_interface_N, general.f_interface_N, rtol=0, atol=1e-6)
