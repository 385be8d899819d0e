"""The physics engine: the paper's figures, exactness, force balance, determinism, stepping."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import Drive, ParameterError, Simulator, build_model

FN = 300.0
V = 1e-5


@pytest.fixture(scope="module")
def paper_run():
    return Simulator(build_model("paper")).run(Drive.constant(FN, V, 60.0))


def _stick_slope(res, t0, t1, frac=(0.2, 0.8)):
    """dFt/d(delta) fitted over the middle of a stick phase [t0, t1]."""
    a = t0 + frac[0] * (t1 - t0)
    b = t0 + frac[1] * (t1 - t0)
    m = (res.t_s >= a) & (res.t_s <= b)
    return np.polyfit(res.delta_m[m], res.ft_N[m], 1)[0]


def test_initial_stage_reaches_mu_smax_fn_with_falling_stiffness(paper_run):
    res = paper_run
    first = res.events[0]
    assert first.stage == "initial"
    ini = res.stage == 0
    assert abs(res.ft_N[ini].max() - 0.2 * FN) <= 0.03 * 0.2 * FN
    # instantaneous stiffness dFt/ddelta along the initial stage, in 6 force bands: falls
    ft, d = res.ft_N[ini], res.delta_m[ini]
    edges = np.linspace(2.0, 58.0, 7)
    slopes = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        m = (ft >= lo) & (ft <= hi)
        slopes.append(np.polyfit(d[m], ft[m], 1)[0])
    assert all(s2 < s1 for s1, s2 in zip(slopes[:-1], slopes[1:], strict=True)), slopes
    assert slopes[0] > 2.5 * slopes[-1]
    # then drops fast: the slip takes under a millisecond and sheds most of the force
    assert first.t_end_s - first.t_start_s < 1e-3
    assert first.drop_N > 0.5 * first.peak_N


def test_stable_stage_peaks_and_constant_stick_stiffness(paper_run):
    res = paper_run
    stable = [e for e in res.events if e.stage == "stable"]
    assert len(stable) >= 8
    # the sampled maximum of every stable cycle is mu_s * Fn within 5 %
    starts = [e.t_end_s for e in res.events]
    for t0, t1 in zip(starts[:-1], starts[1:], strict=True):
        m = (res.t_s > t0) & (res.t_s < t1)
        assert abs(res.ft_N[m].max() - 0.15 * FN) <= 0.05 * 0.15 * FN
    # nearly constant instantaneous stiffness in stick, and K(1) above the stable K(i)
    k_stable = [
        _stick_slope(res, a.t_end_s, b.t_start_s)
        for a, b in zip(res.events[:-1], res.events[1:], strict=True)
    ]
    assert np.std(k_stable) / np.mean(k_stable) < 0.02
    assert np.mean(k_stable) == pytest.approx(0.9e6, rel=0.05)  # Kts
    k1 = _stick_slope(res, 0.0, res.events[0].t_start_s, frac=(0.0, 0.1))
    assert k1 > 1.2 * np.mean(k_stable)


def test_output_rate_does_not_change_the_solution():
    """Samples at 1024 Hz equal every 8th sample at 8192 Hz: the solution is exact between events,
    so the output grid does not perturb it."""
    drive = Drive.constant(FN, V, 20.0)
    model = build_model("paper")
    coarse = Simulator(model, 1024.0).run(drive)
    fine = Simulator(model, 8192.0).run(drive)
    np.testing.assert_allclose(fine.ft_N[::8], coarse.ft_N, atol=1e-6)
    assert [round(e.t_start_s, 9) for e in fine.events] == [
        round(e.t_start_s, 9) for e in coarse.events
    ]


def test_converges_to_a_fine_step_reference():
    """An independent fixed-step RK4 of the stick phase (1 us steps) agrees with the exact solution
    over the first 20 ms, ringing included (the drive starts abruptly from rest)."""
    model = build_model("classic")
    res = Simulator(model, 1024.0).run(Drive.constant(FN, 1e-3, 1.0))
    assert not res.events or res.events[0].t_start_s > 0.02
    m, c0, k0, kt = 0.048, 4.0, 1.475e6, 0.9e6
    h = 1.0 / (1024 * 1024)  # ~1 us, an integer fraction of the sample interval
    n = 1024 * 20  # 20 ms
    x = 0.0
    v = 0.0

    def acc(t: float, x: float, v: float) -> float:
        xs = 1e-3 * t
        return (k0 * (xs - x) + c0 * (1e-3 - v) - kt * x) / m

    xs_ref = []
    for i in range(n):
        t = i * h
        k1x, k1v = v, acc(t, x, v)
        k2x, k2v = v + 0.5 * h * k1v, acc(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v)
        k3x, k3v = v + 0.5 * h * k2v, acc(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v)
        k4x, k4v = v + h * k3v, acc(t + h, x + h * k3x, v + h * k3v)
        x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
        v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        xs_ref.append(x)
    ref = np.array(xs_ref)
    k = np.arange(1, 20)  # samples at 1/1024 s within 20 ms
    idx = k * 1024 - 1
    np.testing.assert_allclose(res.x_specimen_m[k], ref[idx], rtol=0, atol=1e-12)


def test_force_balance_in_stick_and_slip():
    """M dV/dt = K0 (xs - X) + C0 (vs - V) - F_interface at every sample (central differences)."""
    res = Simulator(build_model("paper"), 262144.0).run(Drive.constant(FN, 1e-4, 1.3))
    dt = 1.0 / 262144.0
    acc = (res.v_specimen_m_s[2:] - res.v_specimen_m_s[:-2]) / (2 * dt)
    fd = 1.475e6 * (res.x_stage_m - res.x_specimen_m) + 4.0 * (1e-4 - res.v_specimen_m_s)
    resid = 0.048 * acc - (fd - res.f_interface_N)[1:-1]
    # away from the instants where an element changes state (force jumps there)
    jump = np.abs(np.diff(res.element_mode.astype(int), axis=0)).sum(axis=1) > 0
    near = np.zeros(res.n_samples - 2, dtype=bool)
    for i in np.flatnonzero(jump):
        near[max(0, i - 3): i + 3] = True
    assert np.abs(resid[~near]).max() < 0.05  # N, against forces of tens of N
    # quasi-static stick: the sensor reads the interface force
    m = (res.t_s > 0.5) & (res.t_s < 0.6)
    assert np.abs(res.ft_N[m] - res.f_interface_N[m]).max() < 0.05


def test_deterministic_and_seeded_noise():
    drive = Drive.constant(FN, V, 15.0)
    sim = Simulator(build_model("paper", effects=["rate_state", "sensor_dynamics"]))
    a = sim.run(drive, noise=True, seed=7)
    b = sim.run(drive, noise=True, seed=7)
    c = sim.run(drive, noise=True, seed=8)
    assert np.array_equal(a.ft_N, b.ft_N) and np.array_equal(a.d1_m, b.d1_m)
    assert not np.array_equal(a.ft_N, c.ft_N)
    # noise is quantised to the force LSB
    assert np.allclose(np.round(a.ft_N / 0.02) * 0.02, a.ft_N)


def test_stepper_matches_a_whole_run():
    model = build_model("paper")
    sim = Simulator(model)
    whole = sim.run(Drive.constant(FN, V, 20.0))
    st = sim.stepper(x_stage_m=0.0, fn_N=FN)
    parts = []
    t = 0.0
    rng = np.random.default_rng(0)
    while t < 20.0:
        t = min(20.0, t + float(rng.uniform(0.01, 0.7)))
        parts.append(st.advance(t, V * t, FN))
    ft = np.concatenate([p.ft_N for p in parts])
    assert ft.shape == whole.ft_N.shape
    np.testing.assert_allclose(ft, whole.ft_N, atol=1e-6)
    assert st.state.n_slips == len(whole.events)
    assert st.state.stage == 1


def test_reversal_gives_backward_slips():
    drive = Drive.segments(FN, [(20.0, 1e-5), (40.0, -1e-5)])
    res = Simulator(build_model("paper")).run(drive)
    back = [e for e in res.events if e.peak_N < 0]
    assert back, "no backward slip after reversal"
    assert all(e.slip_m < 0 for e in back)
    assert min(res.ft_N) == pytest.approx(-0.15 * FN, rel=0.05)


def test_hold_keeps_stick():
    res = Simulator(build_model("paper")).run(Drive.segments(FN, [(5.0, 1e-5), (10.0, 0.0)]))
    m = res.t_s > 6.0
    assert not res.slipping[m].any()
    assert np.ptp(res.ft_N[m]) < 0.01


@pytest.mark.parametrize(
    "kwargs",
    [
        {"base": "quantum"},
        {"effects": ["nope"]},
        {"params": {"mu_s": float("nan")}},
        {"params": {"mu_s": -1.0}},
        {"params": {"nonsense": 1.0}},
        {"effects": ["rate_state"], "effect_params": {"rate_state": {"zz": 1.0}}},
    ],
)
def test_bad_model_arguments_are_named(kwargs):
    with pytest.raises(ParameterError):
        build_model(**kwargs)


@pytest.mark.parametrize("fn", [-1.0, float("nan"), float("inf")])
def test_drive_refuses_bad_normal_force(fn):
    with pytest.raises(ParameterError):
        Drive.constant(fn, V, 1.0)


def test_a_model_of_another_rig_is_not_bound_by_this_rigs_load_limit():
    """800 N bounds commands to this rig (rigctl simulate, the stages), not a model of data: a
    rock biax at 20 kN is simulated at its own scale."""
    drive = Drive.constant(20_000.0, V, 0.5)
    res = Simulator(build_model("paper"), sample_rate_hz=1024.0).run(drive)
    assert res.fn_N.max() == pytest.approx(20_000.0)


def test_parameter_table_has_units_and_bounds():
    rows = build_model("paper", effects=["wear"]).parameter_table()
    names = {r.name for r in rows}
    assert {"mu_s", "mu_smax", "kt0_N_per_m", "wear.dmu_s"} <= names
    for r in rows:
        assert r.unit and r.lower <= r.value <= r.upper and r.doc


# --- cases found by the simulated rig: each must finish and return sound results -------------------


def test_no_contact_and_zero_length_steps_return():
    st = Simulator(build_model("paper")).stepper(x_stage_m=0.0, fn_N=0.0)
    r = st.advance(0.1, 0.0, 0.0)
    assert r.n_samples == 103 and np.all(r.ft_N == 0.0)
    assert st.advance(0.1, 0.0, 0.0).n_samples == 0
    # apart, the specimen follows the drive: the stage moves, no friction force appears
    r = st.advance(0.6, 5e-6, 0.0)
    assert np.all(r.f_interface_N == 0.0)
    assert abs(r.ft_N[-1]) < 1e-3


def test_micro_newton_load_with_moving_stage_is_fast_and_frictionless():
    st = Simulator(build_model("paper")).stepper(x_stage_m=0.0, fn_N=5e-6)
    r = st.advance(4 / 1024, 1e-7, 5e-6)
    assert r.n_samples == 5
    assert np.all(np.abs(r.f_interface_N) < 1e-5)


def test_end_time_a_hair_off_the_sample_grid_writes_every_sample():
    st = Simulator(build_model("paper")).stepper(x_stage_m=0.0, fn_N=FN)
    r = st.advance(17.75 - 1e-14, 17.75 * V, FN)
    assert r.t_s[-1] == 17.75
    assert np.all(np.abs(r.ft_N) <= 0.25 * FN)


def test_chattering_near_zero_load_is_bounded_and_reported():
    model = build_model("paper", effects=["normal_coupling", "load_dependent_stiffness"])
    st = Simulator(model).stepper(x_stage_m=0.0, fn_N=0.01)
    st.advance(1 / 1024, 0.0, 0.3)
    r = st.advance(2.0, 2e-5, FN)
    assert np.all(np.isfinite(r.ft_N))
    assert st.state.t_s == 2.0


def test_loss_of_contact_mid_run_unloads_the_interface():
    drive = Drive(np.array([0.0, 8.0, 8.5, 12.0]), np.array([0.0, 8e-5, 8.5e-5, 1.2e-4]),
                  np.array([FN, FN, 0.0, 0.0]))
    res = Simulator(build_model("paper")).run(drive)
    apart = res.t_s > 8.6
    assert np.all(res.f_interface_N[apart] == 0.0)
    assert np.abs(res.ft_N[res.t_s > 11.0]).max() < 0.1


def test_duration_rounding_below_a_sample_time_still_writes_the_last_sample():
    res = Simulator(build_model("classic")).run(Drive.constant(FN, 1e-4, 3e-4 / 1e-4))
    assert res.t_s[-1] == 3.0
    assert abs(res.ft_N[-1]) <= 0.2 * FN


def test_event_trough_is_the_true_minimum_of_the_drive_force():
    """Against the drive force sampled every 0.24 us through the slips (the extremum of one
    half-swing lies slightly before the velocity returns to zero, because of the C0 V term)."""
    rate = 2.0**22
    res = Simulator(build_model("paper"), rate).run(Drive.constant(FN, 1e-3, 0.2))
    assert len(res.events) >= 2
    for e in res.events:
        m = (res.t_s >= e.t_start_s) & (res.t_s <= e.t_end_s)
        assert e.trough_N <= res.ft_N[m].min() + 1e-9
        assert e.trough_N == pytest.approx(res.ft_N[m].min(), abs=1e-4)
        assert e.peak_N == pytest.approx(res.ft_N[res.t_s <= e.t_start_s][-1], abs=0.05)


def test_a_new_contact_starts_a_new_initial_stage():
    """Unload completely, slide back, settle, reload: the first peak is mu_s,max Fn again
    (paper Sec. 2.2)."""
    t = np.array([0.0, 20.0, 20.5, 25.0, 26.0, 26.5, 47.0])
    x = np.array([0.0, 2e-4, 2e-4, 0.0, 0.0, 0.0, 2.05e-4])
    fn = np.array([FN, FN, 0.0, 0.0, 0.0, FN, FN])
    res = Simulator(build_model("paper")).run(Drive(t, x, fn))
    initial = [e for e in res.events if e.stage == "initial"]
    assert len(initial) == 2
    assert initial[1].t_start_s > 26.5
    assert initial[1].peak_N == pytest.approx(0.2 * FN, rel=0.01)
