"""The effect library: documented parameters, exact reduction at `off`, and each effect's signature.

Each signature test compares a model with the effect against the same model without it and checks the
direction (and where the effect's equation predicts it, the size) of the change listed in
docs/model.md and in the effect's docstring. Drives are short (mostly 1e-4 m/s, a few seconds).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pytest

from rigctl.model import (
    LIBRARY,
    Drive,
    ParameterError,
    SimResult,
    Simulator,
    SlipEvent,
    build_model,
    effect_names,
)
from rigctl.model.params import BASE_PARAMS, check_values

FN = 300.0
V = 1e-4  # 10x the paper's drive velocity: same physics, 10x shorter runs
BASE_VALUES = check_values(BASE_PARAMS, {}, "base")
CANONICAL = (
    "stress_evolution", "stribeck", "rate_state", "load_dependent_friction",
    "load_dependent_stiffness", "contact_degradation", "presliding", "interface_damping", "wear",
    "normal_coupling", "sensor_dynamics", "probe_drift",
)


def simulate(
    base: str,
    effects: Sequence[str],
    drive: Drive,
    effect_params: Mapping[str, Mapping[str, float]] | None = None,
    rate_hz: float = 1024.0,
) -> SimResult:
    model = build_model(base, effects=list(effects), effect_params=effect_params)
    return Simulator(model, rate_hz).run(drive)


def stable_events(res: SimResult) -> list[SlipEvent]:
    return [e for e in res.events if e.stage == "stable"]


def stick_slope(
    res: SimResult, t0: float, t1: float, frac: tuple[float, float], settle_s: float = 0.0
) -> float:
    """dFt/d(delta) [N/m] fitted over the fraction `frac` of the stick phase [t0, t1], starting no
    earlier than `settle_s` after t0 (the ringing after a slip decays as exp(-C0 t / 2M), 24 ms)."""
    a, b = max(t0 + frac[0] * (t1 - t0), t0 + settle_s), t0 + frac[1] * (t1 - t0)
    m = (res.t_s >= a) & (res.t_s <= b)
    assert m.sum() >= 5, "too few samples in the fitted window"
    return float(np.polyfit(res.delta_m[m], res.ft_N[m], 1)[0])


def stable_stick_slopes(res: SimResult, frac: tuple[float, float] = (0.2, 0.9)) -> list[float]:
    """Stick slopes between consecutive slips, fitted after the ringing has decayed (0.15 s)."""
    ev = res.events
    return [
        stick_slope(res, a.t_end_s, b.t_start_s, frac, settle_s=0.15)
        for a, b in zip(ev[:-1], ev[1:], strict=True)
    ]


def mixed_drive() -> Drive:
    """Slides, a hold, a normal-force change, a reversal with a rising Fn: every code path."""
    t = np.array([0.0, 2.5, 3.0, 3.5, 4.5, 7.0])
    x = V * np.array([0.0, 2.5, 2.5, 2.5, 1.5, -1.0])
    fn = np.array([FN, FN, FN, 260.0, 260.0, 330.0])
    return Drive(t, x, fn)


# --- (1) documented parameters ----------------------------------------------------------------

def test_library_holds_the_twelve_canonical_effects_in_spec_order():
    assert tuple(LIBRARY) == CANONICAL
    assert effect_names() == list(CANONICAL)
    for name, cls in LIBRARY.items():
        assert cls.name == name


@pytest.mark.parametrize("name", CANONICAL)
def test_effect_is_documented_with_units_bounds_and_off(name):
    cls = LIBRARY[name]
    eff = cls()
    assert cls.summary and cls.signature and cls.reveal_protocol
    module_doc = __import__(cls.__module__, fromlist=["_"]).__doc__ or ""
    assert f"``{name}``" in module_doc and "Off:" in module_doc, "docstring: equation, source, off"
    assert cls.params, "an effect without parameters cannot be identified or switched off"
    names = [p.name for p in cls.params]
    assert len(set(names)) == len(names)
    off = eff.off_values(BASE_VALUES)
    assert set(off) == set(names)
    for p in cls.params:
        assert p.unit and p.doc, p.name
        assert math.isfinite(p.lower) and math.isfinite(p.upper) and p.lower < p.upper, p.name
        assert p.lower <= p.default <= p.upper, p.name
        assert p.lower <= off[p.name] <= p.upper, p.name
        # the unit is in the name where the quantity has one (style: names carry the unit)
        if p.unit != "-":
            assert p.name.endswith(("_m", "_s", "_N", "_per_m", "_per_s", "_N_s_per_m")), p.name
    # at least one parameter's default differs from off: the effect does something by default
    assert eff.default_values(BASE_VALUES) != off


# --- (2) off reduces the model exactly to the base ----------------------------------------------

def _assert_identical(a: SimResult, b: SimResult) -> None:
    for col in ("ft_N", "fn_N", "d1_m", "d2_m", "delta_m", "f_interface_N", "x_specimen_m"):
        assert np.array_equal(getattr(a, col), getattr(b, col)), col
    assert a.events == b.events


@pytest.fixture(scope="module")
def base_runs() -> dict[str, SimResult]:
    return {base: simulate(base, [], mixed_drive()) for base in ("classic", "paper")}


@pytest.mark.parametrize("base", ["classic", "paper"])
@pytest.mark.parametrize("name", [n for n in CANONICAL if n != "stress_evolution"])
def test_effect_at_off_values_is_exactly_the_base(name, base, base_runs):
    off = LIBRARY[name]().off_values(BASE_VALUES)
    res = simulate(base, [name], mixed_drive(), {name: off})
    ref = base_runs[base]
    assert len(ref.events) >= 8  # the drive really exercises slips in both directions
    _assert_identical(res, ref)
    # and at its defaults it does change the output (probe_drift: the probe signal only)
    on = simulate(base, [name], mixed_drive())
    col = "d1_m" if name == "probe_drift" else "ft_N"
    assert not np.array_equal(getattr(on, col), getattr(ref, col))


def test_stress_evolution_off_is_classic_and_on_is_paper(base_runs):
    off = LIBRARY["stress_evolution"]().off_values(BASE_VALUES)
    assert off == {"kt0_N_per_m": 0.9e6, "mu_smax": 0.15, "p_slope": 0.0}
    _assert_identical(
        simulate("classic", ["stress_evolution"], mixed_drive(), {"stress_evolution": off}),
        base_runs["classic"],
    )
    _assert_identical(simulate("classic", ["stress_evolution"], mixed_drive()), base_runs["paper"])
    # adding it to `paper`, where it is part of the base, changes nothing
    assert build_model("paper", effects=["stress_evolution"]).values() == build_model("paper").values()


# --- (3) signatures -----------------------------------------------------------------------------

def test_stress_evolution_bends_the_initial_stage_and_k1_exceeds_stable_k():
    drive = Drive.constant(FN, V, 3.0)

    def band_slopes(res: SimResult) -> list[float]:
        ini = res.stage == 0
        ft, d = res.ft_N[ini], res.delta_m[ini]
        top = 0.97 * ft.max()
        edges = np.linspace(5.0, top, 6)
        out = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            m = (ft >= lo) & (ft <= hi)
            out.append(float(np.polyfit(d[m], ft[m], 1)[0]))
        return out

    classic = band_slopes(simulate("classic", [], drive))
    assert np.ptp(classic) < 0.01 * np.mean(classic)  # straight: the model without it
    for slope_s in (0.5, 0.9):
        res = simulate("classic", ["stress_evolution"], drive, {"stress_evolution": {"p_slope": slope_s}})
        s = band_slopes(res)
        assert all(b < a for a, b in zip(s[:-1], s[1:], strict=True)), s
        k1 = stick_slope(res, 0.0, res.events[0].t_start_s, (0.02, 0.1))
        k_stable = np.mean(stable_stick_slopes(res))
        assert k1 > 1.2 * k_stable
        if slope_s == 0.5:
            bend_half = s[0] / s[-1]
        else:
            assert s[0] / s[-1] > bend_half  # a steeper stress ramp bends the curve more


def test_rate_state_peaks_after_holds_grow_with_log_hold_time():
    holds = (1.0, 10.0, 100.0)
    segs: list[tuple[float, float]] = [(2.0, V)]
    for h in holds:
        segs += [(h, 0.0), (1.0, V)]
    drive = Drive.segments(FN, segs)
    hold_ends = np.cumsum([s[0] for s in segs])[1::2]

    def first_peaks(res: SimResult) -> tuple[np.ndarray, np.ndarray]:
        peaks, ages = [], []
        for t_end in hold_ends:
            nxt = next(e for e in res.events if e.t_start_s > t_end)
            prev = [e for e in res.events if e.t_end_s < t_end][-1]
            peaks.append(nxt.peak_N)
            ages.append(nxt.t_start_s - prev.t_end_s)  # time in stationary contact
        return np.array(peaks), np.array(ages)

    flat, _ = first_peaks(simulate("paper", [], drive))
    assert np.ptp(flat) < 0.01  # without it, the hold leaves no trace
    b = 0.004
    peaks, ages = first_peaks(simulate("paper", ["rate_state"], drive, {"rate_state": {"b": b}}))
    slope, icpt = np.polyfit(np.log(holds), peaks, 1)
    assert slope > 0.5
    resid = peaks - (slope * np.log(holds) + icpt)
    assert np.abs(resid).max() < 0.1 * np.ptp(peaks)  # near-linear in log hold
    # aging law: d(peak)/d ln(contact age) = b Fn
    slope_age = np.polyfit(np.log(ages), peaks, 1)[0]
    assert slope_age == pytest.approx(b * FN, rel=0.05)


def _sweep(effects: Sequence[str], fns: Sequence[float]) -> list[SimResult]:
    return [simulate("paper", effects, Drive.constant(fn, V, 4.0)) for fn in fns]


FNS = (150.0, 200.0, 250.0, 300.0, 350.0)


def test_load_dependent_friction_makes_peak_and_trough_ratios_depend_on_fn():
    def ratios(runs: list[SimResult]) -> tuple[np.ndarray, np.ndarray]:
        pk, tr = [], []
        for fn, res in zip(FNS, runs, strict=True):
            st = stable_events(res)[1:]
            assert len(st) >= 3
            pk.append(np.mean([e.peak_N for e in st]) / fn)
            tr.append(np.mean([e.trough_N for e in st]) / fn)
        return np.array(pk), np.array(tr)

    pk0, tr0 = ratios(_sweep([], FNS))
    assert np.ptp(pk0) < 1e-3 * pk0.mean() and np.ptp(tr0) < 5e-3 * tr0.mean()
    pk, tr = ratios(_sweep(["load_dependent_friction"], FNS))
    assert np.all(np.diff(pk) > 0) and np.all(np.diff(tr) > 0)
    # mu_s (Fn/Fn_ref)^alpha_s with the default alpha_s = 0.3
    assert pk[-1] / pk[0] == pytest.approx((350.0 / 150.0) ** 0.3, rel=0.01)


def test_load_dependent_stiffness_grows_with_fn_at_a_falling_rate():
    def slopes(runs: list[SimResult]) -> tuple[np.ndarray, np.ndarray]:
        ks, k1 = [], []
        for res in runs:
            ks.append(np.mean(stable_stick_slopes(res)))
            k1.append(stick_slope(res, 0.0, res.events[0].t_start_s, (0.02, 0.1)))
        return np.array(ks), np.array(k1)

    ks0, k10 = slopes(_sweep([], FNS))
    assert np.ptp(ks0) < 0.01 * ks0.mean() and np.ptp(k10) < 0.01 * k10.mean()
    ks, k1 = slopes(_sweep(["load_dependent_stiffness"], FNS))
    for k in (ks, k1):
        growth = np.diff(k)  # equal Fn steps
        assert np.all(growth > 0), k
        assert np.all(np.diff(growth) < 0), growth


def test_contact_degradation_stick_slopes_fall_over_cycles_then_settle():
    drive = Drive.constant(FN, V, 6.0)
    flat = stable_stick_slopes(simulate("paper", [], drive))
    assert np.ptp(flat) < 0.01 * np.mean(flat)
    k = np.array(stable_stick_slopes(simulate("paper", ["contact_degradation"], drive)))
    assert len(k) >= 12
    assert np.all(np.diff(k[:6]) < 0), k
    assert k[0] > 1.2 * k[-1]
    assert np.ptp(k[-3:]) < 0.02 * k[-1]  # later cycles nearly equal
    # Kts (1 + A exp(-(n - 1) / n_c)) with A = 0.3, n_c = 3: in stick Ft balances the interface
    # force, so dFt/d(delta) is the interface stiffness itself
    n = np.arange(1, len(k) + 1)
    np.testing.assert_allclose(k, 0.9e6 * (1 + 0.3 * np.exp(-(n - 1) / 3.0)), rtol=0.02)


def test_sensor_dynamics_smears_drops_as_a_first_order_lag():
    drive = Drive.constant(FN, V, 3.0)
    rate = 8192.0  # resolves the sub-millisecond slips and the ringing after them
    tau = 3e-3
    ideal = simulate("paper", [], drive, rate_hz=rate)
    lagged = simulate("paper", ["sensor_dynamics"], drive, {"sensor_dynamics": {"tau_s": tau}},
                      rate_hz=rate)
    assert np.abs(np.diff(lagged.ft_N)).max() < 0.3 * np.abs(np.diff(ideal.ft_N)).max()
    # the mechanics are untouched
    np.testing.assert_allclose(lagged.x_specimen_m, ideal.x_specimen_m, rtol=0, atol=1e-12)
    assert len(lagged.events) == len(ideal.events) >= 4

    # the fall from the peak to the mid level takes longer: a slip (< 1 ms) vs ~ tau ln 2 and more
    def fall_time_s(res: SimResult, e: SlipEvent) -> float:
        i0 = int(np.searchsorted(res.t_s, e.t_start_s))
        mid = 0.5 * (e.peak_N + e.trough_N)
        return float(np.argmax(res.ft_N[i0:] < mid)) / rate

    for e in stable_events(ideal):
        assert fall_time_s(ideal, e) < 1e-3
        assert fall_time_s(lagged, e) > 0.5 * tau

    # tau dy/dt = F - y: in stick the residual y - F follows -tau dy/dt
    dydt = np.gradient(lagged.ft_N, 1.0 / rate)
    quiet = ideal.stage == 1  # the stable stage: no element events bending F(t)
    for e in ideal.events:  # away from slips and the ringing after them (decay time 2M/C0 = 24 ms)
        quiet &= ~((ideal.t_s > e.t_start_s - 0.01) & (ideal.t_s < e.t_end_s + 0.2))
    assert quiet.sum() > 0.3 * rate
    lag = lagged.ft_N - ideal.ft_N
    assert np.abs(lag[quiet]).max() > 0.1  # a visible lag in stick (load rate ~56 N/s)
    np.testing.assert_allclose(lag[quiet], -tau * dydt[quiet], atol=3e-3)


def test_stribeck_drop_and_trough_depend_on_slip_and_drive_velocity():
    """Slips reach ~0.05 m/s; the friction is raised above mu_k while |V| is within a few v_s of 0:
    at the onset of each slip, and (as far as the elements can take it up elastically) as it stops.

    A larger v_s: higher trough, smaller drop. A drive velocity approaching v_s: slips start already
    on the falling branch of the curve and stay smaller (stick-slip fades towards steady sliding),
    while the base's drop changes far less. (At drive velocities << v_s, 1e-4 vs 3e-4 m/s, the
    drops are the same within 0.1 N: that is the physics, the onset starts from V << v_s either way.)
    """
    def drop_trough(
        effects: Sequence[str], v: float, vs: float | None = None
    ) -> tuple[float, float]:
        ep = None if vs is None else {"stribeck": {"vs_m_per_s": vs}}
        res = simulate("classic", effects, Drive.constant(FN, v, max(3e-4 / v, 0.5)), ep)
        st = stable_events(res)[1:]
        assert len(st) >= 3
        return float(np.mean([e.drop_N for e in st])), float(np.mean([e.trough_N for e in st]))

    d0, u0 = drop_trough([], 1e-4)
    drops, troughs = zip(
        *(drop_trough(["stribeck"], 1e-4, vs) for vs in (1e-3, 5e-3, 1e-2, 2e-2)), strict=True
    )
    assert np.all(np.diff(troughs) > 0) and np.all(np.diff(drops) < 0)
    assert troughs[0] > u0 and troughs[-1] > u0 + 5.0
    # drive velocity: 1e-4 m/s << v_s = 5e-3 m/s vs 1e-2 m/s = 2 v_s
    s_slow, _ = drop_trough(["stribeck"], 1e-4)
    s_fast, _ = drop_trough(["stribeck"], 1e-2)
    d_fast, _ = drop_trough([], 1e-2)
    assert s_fast < 0.6 * s_slow
    assert d_fast > 0.8 * d0
    assert s_fast < 0.7 * d_fast


def test_presliding_rounds_off_the_stick_ramp_before_the_peak():
    drive = Drive.constant(FN, V, 5.0)

    def roundness(res: SimResult) -> np.ndarray:
        early = np.array(stable_stick_slopes(res, (0.1, 0.5)))
        late = np.array(stable_stick_slopes(res, (0.9, 0.99)))
        return late / early

    plain = simulate("paper", [], drive)
    assert np.all(np.abs(roundness(plain) - 1.0) < 0.02)
    res = simulate("paper", ["presliding"], drive)
    assert len(res.events) >= 4
    assert np.all(roundness(res) < 0.6)
    # the peak stays mu_s Fn (mean of the threshold multipliers is 1)
    for e in stable_events(res):
        assert e.peak_N == pytest.approx(0.15 * FN, rel=0.01)


def test_interface_damping_makes_ringing_after_a_slip_decay_faster():
    rate = 16384.0
    drive = Drive.constant(FN, V, 1.0)  # classic: one slip at ~0.8 s, then ringing in stick

    def decay_rate(res: SimResult) -> float:
        t_end = res.events[0].t_end_s

        def rms(a: float, b: float) -> float:
            m = (res.t_s >= t_end + a) & (res.t_s < t_end + b)
            v = res.v_specimen_m_s[m]
            return float(np.sqrt(np.mean((v - v.mean()) ** 2)))

        return math.log(rms(0.001, 0.006) / rms(0.006, 0.011)) / 0.005

    m_kg, c0 = 0.048, 4.0
    s0 = decay_rate(simulate("classic", [], drive, rate_hz=rate))
    assert s0 == pytest.approx(c0 / (2 * m_kg), rel=0.15)
    c = 30.0
    s1 = decay_rate(
        simulate("classic", ["interface_damping"], drive, {"interface_damping": {"c_N_s_per_m": c}},
                 rate_hz=rate)
    )
    assert s1 == pytest.approx((c0 + c) / (2 * m_kg), rel=0.15)  # damped oscillator: C / 2M


def test_wear_drifts_event_sizes_with_cumulative_slip():
    drive = Drive.constant(FN, V, 4.0)
    flat = stable_events(simulate("classic", [], drive))
    assert np.ptp([e.peak_N for e in flat]) < 0.01
    res = simulate("classic", ["wear"], drive)
    ev = res.events
    assert len(ev) >= 8
    peaks = np.array([e.peak_N for e in ev])
    troughs = np.array([e.trough_N for e in ev])
    assert np.all(np.diff(peaks[1:]) > 0) and np.all(np.diff(troughs[1:]) > 0)
    assert peaks[-1] - peaks[1] > 1.0
    # mu_s + dmu_s (1 - exp(-s / s_w)), s = cumulative slip before each event (defaults)
    s_before = np.cumsum([0.0] + [abs(e.slip_m) for e in ev[:-1]])
    expected = (0.15 + 0.02 * (1.0 - np.exp(-s_before[1:] / 3e-4))) * FN
    np.testing.assert_allclose(peaks[1:], expected, atol=0.02)


def test_normal_coupling_moves_fn_with_ft_and_during_slips():
    drive = Drive.constant(FN, V, 3.0)
    plain = simulate("classic", [], drive)
    assert np.all(plain.fn_N == FN)
    kappa = 0.1
    res = simulate("classic", ["normal_coupling"], drive, {"normal_coupling": {"kappa": kappa}})
    assert np.corrcoef(res.fn_N, res.ft_N)[0, 1] > 0.999
    st = stable_events(res)
    for e in st:
        i0 = int(np.searchsorted(res.t_s, e.t_start_s)) - 1
        i1 = int(np.searchsorted(res.t_s, e.t_end_s)) + 1
        assert res.fn_N[i0] - res.fn_N[i1] > 0.3 * kappa * e.drop_N  # Fn moves during the slip
    # the threshold uses Fn + kappa Ft: peak = mu_s Fn / (1 - mu_s kappa)
    for e in st:
        assert e.peak_N == pytest.approx(0.15 * FN / (1 - 0.15 * kappa), rel=2e-3)


def test_probe_drift_grows_delta_at_equal_force_over_a_hold():
    drive = Drive.segments(FN, [(0.3, V), (20.0, 0.0)])
    rate_m_s = 5e-8
    res = simulate("paper", ["probe_drift"], drive, {"probe_drift": {"rate_m_per_s": rate_m_s}})
    plain = simulate("paper", [], drive)
    hold = res.t_s > 0.6
    assert np.ptp(res.ft_N[hold]) < 0.01  # equal force
    measured = res.d1_m - res.d2_m
    assert np.polyfit(res.t_s[hold], measured[hold], 1)[0] == pytest.approx(rate_m_s, rel=1e-6)
    assert abs(np.polyfit(plain.t_s[hold], (plain.d1_m - plain.d2_m)[hold], 1)[0]) < 1e-12
    assert np.array_equal(res.ft_N, plain.ft_N)  # only the measurement drifts


def test_probe_drift_continues_across_stepper_chunks():
    """A virtual rig steps the model in chunks: the drift is a function of run time, not chunk time."""
    model = build_model("paper", effects=["probe_drift"])
    sim = Simulator(model)
    whole = sim.run(Drive.constant(FN, V, 3.0))
    st = sim.stepper(x_stage_m=0.0, fn_N=FN)
    parts = [st.advance(t, V * t, FN) for t in (0.7, 1.5, 2.2, 3.0)]
    d1 = np.concatenate([p.d1_m for p in parts])
    np.testing.assert_allclose(d1, whole.d1_m, rtol=0, atol=1e-12)


# --- composition and named errors ------------------------------------------------------------------

def test_composition_by_name_with_overridden_parameters():
    spec = build_model(
        "paper",
        effects=["wear", "contact_degradation", "sensor_dynamics"],
        params={"mu_k": 0.09, "mu_smax": 0.21},
        effect_params={"wear": {"dmu_s": 0.05}, "sensor_dynamics": {"tau_s": 1e-3}},
    )
    assert spec.effect_names == ["wear", "contact_degradation", "sensor_dynamics"]
    vals = spec.values()
    assert vals["mu_k"] == 0.09 and vals["mu_smax"] == 0.21
    assert vals["wear.dmu_s"] == 0.05 and vals["wear.dmu_k"] == 0.02  # default kept
    assert vals["sensor_dynamics.tau_s"] == 1e-3
    table = {r.name: r for r in spec.parameter_table()}
    assert table["wear.dmu_s"].owner == "wear" and table["wear.dmu_s"].unit == "-"
    assert table["sensor_dynamics.tau_s"].unit == "s"
    # the order in which effects are given does not matter
    drive = Drive.constant(FN, V, 3.0)
    other = build_model(
        "paper",
        effects=["sensor_dynamics", "contact_degradation", "wear"],
        params={"mu_k": 0.09, "mu_smax": 0.21},
        effect_params={"sensor_dynamics": {"tau_s": 1e-3}, "wear": {"dmu_s": 0.05}},
    )
    a, b = Simulator(spec).run(drive), Simulator(other).run(drive)
    assert np.array_equal(a.ft_N, b.ft_N)
    # each composed effect still acts: degradation and wear together differ from either alone
    only_wear = Simulator(build_model("paper", effects=["wear"])).run(drive)
    assert not np.array_equal(a.ft_N, only_wear.ft_N)
    # with_values on a qualified name
    assert spec.with_values({"wear.s_wear_m": 1e-3}).values()["wear.s_wear_m"] == 1e-3


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"effects": ["no_such_effect"]}, "no_such_effect"),
        ({"effects": ["wear"], "effect_params": {"wear": {"dmu_z": 0.1}}}, "dmu_z"),
        ({"effects": ["wear"], "effect_params": {"wear": {"dmu_s": float("nan")}}}, "dmu_s"),
        ({"effects": ["wear"], "effect_params": {"wear": {"dmu_s": 0.9}}}, "dmu_s"),
        ({"effects": ["rate_state"], "effect_params": {"rate_state": {"dc_m": 0.0}}}, "dc_m"),
        ({"effects": ["sensor_dynamics"],
          "effect_params": {"sensor_dynamics": {"tau_s": float("inf")}}}, "tau_s"),
        ({"effects": ["stribeck"], "effect_params": {"stribeck": {"vs_m_per_s": -1e-3}}},
         "vs_m_per_s"),
        ({"effects": ["wear"], "effect_params": {"stribeck": {"vs_m_per_s": 1e-3}}}, "stribeck"),
        ({"effects": ["wear", "wear"]}, "wear"),
        ({"params": {"mu_smax": 9.0}}, "mu_smax"),
        ({"params": {"rate_state.b": 0.01}}, "rate_state"),
        ({"effects": ["presliding"], "effect_params": {"presliding": {"spread": "wide"}}},
         "spread"),
    ],
)
def test_bad_effect_names_and_values_raise_parameter_error_naming_them(kwargs, named):
    with pytest.raises(ParameterError, match=named):
        build_model("paper", **kwargs)


def test_with_values_refuses_nan_and_out_of_bounds_by_name():
    spec = build_model("classic", effects=["rate_state"])
    with pytest.raises(ParameterError, match=r"rate_state\.b"):
        spec.with_values({"rate_state.b": float("nan")})
    with pytest.raises(ParameterError, match=r"rate_state\.a"):
        spec.with_values({"rate_state.a": 0.5})
    with pytest.raises(ParameterError, match="mu_smax"):
        spec.with_values({"mu_smax": 0.2})  # stress_evolution is not in `classic`
