"""The engine agrees with an independent solve_ivp(RK45) solution of the same model.

benchmarks/rk45_reference.py steps the Jenkins-element model with RK45 and restarts at every mode
change located by solve_ivp events; it shares no code with rigctl/model. Correctness, not timing.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.rk45_reference import ReferenceModelError, RK45Reference
from rigctl.model import Drive, Simulator, build_model

FN = 300.0


@pytest.fixture(scope="module")
def first_cycle():
    """Paper model, 2e-4 m/s: the initial stage (elements presliding one by one), the first
    global slip, its ringing, one stable stick phase and the second slip, in 0.85 s."""
    spec = build_model("paper")
    drive = Drive.constant(FN, 2e-4, 0.85)
    eng = Simulator(spec, 1024.0).run(drive)
    ref = RK45Reference(spec, 1024.0, rtol=1e-9, atol_m=1e-14).run(drive)
    return eng, ref


@pytest.mark.slow
def test_first_slip_time_peak_and_trough_agree(first_cycle):
    eng, ref = first_cycle
    assert [e.stage for e in eng.events] == ["initial", "stable"]
    assert [e.stage for e in ref.events] == ["initial", "stable"]
    for a, b in zip(eng.events, ref.events, strict=True):
        assert a.t_start_s == pytest.approx(b.t_start_s, abs=1e-7)
        assert a.t_end_s == pytest.approx(b.t_end_s, abs=1e-7)
        assert a.peak_N == pytest.approx(b.peak_N, abs=1e-4)
        assert a.slip_m == pytest.approx(b.slip_m, abs=1e-10)
        # the engine finds the exact minimum of the drive force over the slip; the reference takes
        # it over a fine grid of its solution, which can only over-estimate it, by under 1 mN
        assert b.trough_N - 1e-3 <= a.trough_N <= b.trough_N + 1e-6
    first = eng.events[0]
    assert first.peak_N == pytest.approx(0.2 * FN, rel=1e-3)  # mu_s,max Fn


def test_force_samples_agree_over_the_first_cycle(first_cycle):
    eng, ref = first_cycle
    assert eng.ft_N.shape == ref.ft_N.shape
    assert np.all(np.isfinite(ref.ft_N))
    assert np.abs(eng.ft_N - ref.ft_N).max() < 5e-3  # N, against forces up to 60 N
    # 2e-9 m of specimen position is 3 mN through K0
    np.testing.assert_allclose(eng.x_specimen_m, ref.x_specimen_m, rtol=0, atol=2e-9)


@pytest.mark.slow
def test_fast_drive_with_reversal_and_backward_slip():
    """At 1e-3 m/s the slips follow each other while the ~1.1 kHz ringing is still alive, and the
    reversal brings backward slips (negative thresholds, V returning to 0 from below)."""
    spec = build_model("paper")
    drive = Drive.segments(FN, [(0.12, 1e-3), (0.2, -1e-3)])
    eng = Simulator(spec, 1024.0).run(drive)
    ref = RK45Reference(spec, 1024.0, rtol=1e-8, atol_m=1e-13).run(drive)
    assert len(eng.events) == len(ref.events) >= 3
    assert any(e.peak_N < 0 for e in ref.events), "no backward slip in the reference"
    for a, b in zip(eng.events, ref.events, strict=True):
        assert a.t_start_s == pytest.approx(b.t_start_s, abs=1e-8)
        assert a.peak_N == pytest.approx(b.peak_N, abs=1e-4)
        assert np.sign(a.slip_m) == np.sign(b.slip_m)
    assert np.abs(eng.ft_N - ref.ft_N).max() < 1e-3


def test_a_loose_reference_is_measurably_off():
    """The agreement above is earned: the same solver at a loose tolerance misses by far more."""
    spec = build_model("paper")
    drive = Drive.constant(FN, 1e-3, 0.2)
    eng = Simulator(spec, 1024.0).run(drive)
    loose = RK45Reference(spec, 1024.0, rtol=1e-4, atol_m=1e-10).run(drive)
    assert np.abs(eng.ft_N - loose.ft_N).max() > 1e-3


@pytest.mark.parametrize("kwargs", [{"effects": ["wear"]}, {"base": "paper", "effects": ["stribeck"]}])
def test_reference_refuses_models_it_does_not_implement(kwargs):
    with pytest.raises(ReferenceModelError):
        RK45Reference(build_model(**kwargs))


def test_reference_refuses_a_varying_normal_force():
    drive = Drive(np.array([0.0, 1.0]), np.array([0.0, 1e-5]), np.array([300.0, 310.0]))
    with pytest.raises(ReferenceModelError):
        RK45Reference(build_model("paper")).run(drive)
