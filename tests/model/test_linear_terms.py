"""Linear terms of the equations of motion (issue 37 section 1): an effect declares a drag -c V on
the slider and a normal coupling kappa through ``Effect.linear_terms``; the exact path integrates
them in closed form. ``interface_damping`` and ``normal_coupling`` are stated this way (one way, the
same as a plug-in's), and a model with them keeps the exact path."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pytest

from rigctl.errors import SimulationError
from rigctl.model import (
    CoreParams,
    Drive,
    Effect,
    LinearTerms,
    ParamSpec,
    SimResult,
    Simulator,
    build_model,
    layout,
)
from rigctl.testing import EffectContract

DRIVE = Drive.constant(300.0, 3e-4, 1.0)
SHS = Drive.segments(250.0, [(1.0, 2e-4), (0.5, 0.0), (1.0, 2e-4)])  # slips, a hold, slips again


class UserDrag(Effect):
    """A user's dashpot at the interface, written from docs/effects.md section 3."""

    name = "user_drag"
    summary = "a dashpot -c V on the slider"
    signature = "ringing after a slip decays faster"
    reveal_protocol = "any run with slips"
    params = (ParamSpec("c_N_s_per_m", 30.0, 0.0, 300.0, "N s/m", "drag coefficient", off=0.0,
                        scales_with="damping"),)

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(damping_N_s_per_m=values["c_N_s_per_m"])


class UserTilt(Effect):
    """A user's normal coupling, Fn_eff = Fn + kappa K0 (x_stage - X)."""

    name = "user_tilt"
    summary = "the normal force follows the drive force"
    signature = "Fn moves with Ft"
    reveal_protocol = "any run recording Fn"
    params = (ParamSpec("kappa", 0.1, -0.5, 0.5, "-", "dFn / dFt", off=0.0),)

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(normal_per_drive_force=values["kappa"])


class UserFlexure(Effect):
    """A user's spring from the slider to the frame, relaxed where the slider starts."""

    name = "user_flexure"
    summary = "a parallel spring -k_p (X - X(0)) on the slider"
    signature = "peaks grow with the distance slid"
    reveal_protocol = "a long slide"
    params = (ParamSpec("k_N_per_m", 2e5, 0.0, 1e7, "N/m", "spring stiffness", off=0.0),)

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(stiffness_N_per_m=values["k_N_per_m"])


def spring_force(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    return -p[0] * x  # the drives below start at x = 0: -k_p (X - X(0))


class ForceTermFlexure(Effect):
    """The same spring as a plug-in force term (the general path integrates it by RK4)."""

    name = "force_term_flexure"
    summary = "a parallel spring as a force term"
    signature = "as user_flexure"
    reveal_protocol = "a long slide"
    params = UserFlexure.params

    @staticmethod
    def force_term() -> Callable[..., Any]:
        return spring_force


class NotFinite(Effect):
    name = "not_finite"
    summary = "a drag that is not a number"
    signature = "none"
    reveal_protocol = "any"
    params = (ParamSpec("on", 1.0, 0.0, 1.0, "-", "active", off=0.0),)

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(damping_N_s_per_m=float("nan") if values["on"] else 0.0)


def _run(effects: list[Any], drive: Drive = DRIVE, base: str = "paper",
         **params: dict[str, float]) -> SimResult:
    return Simulator(build_model(base, effects=effects, effect_params=params or None)).run(drive)


def _same(a: SimResult, b: SimResult) -> None:
    for channel in ("ft_N", "fn_N", "x_specimen_m", "v_specimen_m_s", "f_interface_N"):
        assert np.array_equal(getattr(a, channel), getattr(b, channel)), channel
    assert a.events == b.events
    assert len(a.events) >= 3


@pytest.mark.parametrize("drive", [DRIVE, SHS], ids=["slide", "slide_hold_slide"])
def test_a_user_drag_is_interface_damping_bit_for_bit(drive):
    c = 45.0
    user = _run([UserDrag], drive, user_drag={"c_N_s_per_m": c})
    library = _run(["interface_damping"], drive, interface_damping={"c_N_s_per_m": c})
    _same(user, library)
    assert not np.array_equal(user.ft_N, _run([], drive).ft_N)  # the drag does act


def test_a_user_tilt_is_normal_coupling_bit_for_bit():
    user = _run([UserTilt], SHS, user_tilt={"kappa": -0.08})
    library = _run(["normal_coupling"], SHS, normal_coupling={"kappa": -0.08})
    _same(user, library)
    assert np.ptp(user.fn_N) > 1.0  # Fn moves with the drive force


@pytest.mark.parametrize("effects", [["interface_damping"], ["normal_coupling"], [UserDrag],
                                     ["interface_damping", "normal_coupling", "rate_state"]])
def test_a_model_with_linear_terms_keeps_the_exact_path(effects):
    """No plug-in function term is compiled: the kernel's exact path integrates the model (the
    general path would integrate it by RK4, 300-1900 times slower)."""
    setup = build_model("paper", effects=effects).core_setup()
    assert not setup.terms.active
    assert setup.cp[layout.P_CINT] != 0.0 or setup.cp[layout.P_KAPPA] != 0.0


def test_linear_terms_of_several_effects_add():
    """Two drags in parallel are one drag of their sum (values exact in binary: same bits)."""
    one = _run(["interface_damping"], interface_damping={"c_N_s_per_m": 40.0})
    two = _run(["interface_damping", UserDrag], interface_damping={"c_N_s_per_m": 8.0},
               user_drag={"c_N_s_per_m": 32.0})
    _same(one, two)


def test_the_drag_and_the_coupling_are_set_only_as_linear_terms():
    """One way: a hook cannot set the interface's drag or the normal coupling as coefficients."""
    core = CoreParams(np.zeros(layout.N_PARAMS))
    for name in ("c_interface_N_s_per_m", "kappa"):
        with pytest.raises(KeyError, match="unknown core coefficient"):
            core[name] = 1.0
    for lib in ("interface_damping", "normal_coupling"):
        model = build_model("paper", effects=[lib])
        assert type(model.effects[-1].effect).apply is Effect.apply


def test_a_linear_term_that_is_not_finite_is_refused_naming_the_effect():
    with pytest.raises(SimulationError, match=r"not_finite.*damping_N_s_per_m"):
        build_model("paper", effects=[NotFinite]).core_setup()


def test_at_off_values_linear_terms_leave_the_model_bit_for_bit():
    _same(_run([UserDrag, UserTilt], user_drag={"c_N_s_per_m": 0.0}, user_tilt={"kappa": 0.0}),
          _run([]))


def _x_at(res: SimResult, t_s: float) -> float:
    """X at t_s from the last sample before it (a slip between two samples moves X)."""
    k = int(np.searchsorted(res.t_s, t_s, side="right")) - 1
    return float(res.x_specimen_m[k] + res.v_specimen_m_s[k] * (t_s - res.t_s[k]))


def test_a_parallel_spring_adds_its_force_to_what_the_drive_must_pull():
    """-k_p (X - X(0)) on the slider (classic model: one threshold mu_s Fn): at every slip's start
    the drive carries mu_s Fn + k_p (X - X(0)), within 50 mN: the drive also carries M X'' of the
    ringing the previous slip left (~20 mN at 3e-4 m/s), as in tests/model/test_plugin_terms.py's
    spring; the spring's share grows past 10 N over the run, 200 times that."""
    kp = 2e5
    res = _run([UserFlexure], base="classic", user_flexure={"k_N_per_m": kp})
    assert len(res.events) >= 3
    for e in res.events:
        assert e.peak_N == pytest.approx(0.15 * 300.0 + kp * _x_at(res, e.t_start_s), abs=0.05)
    assert res.events[-1].peak_N > 0.15 * 300.0 + 10.0


@pytest.mark.parametrize("effects", [[], ["rate_state"], ["sensor_dynamics"],
                                     ["presliding", "rate_state"], ["stribeck"]],
                         ids=["paper", "rate_state", "sensor", "presliding_aging", "stribeck"])
def test_a_parallel_spring_on_the_exact_path_agrees_with_the_same_force_on_the_general_path(
        effects):
    """The linear spring on every branch of the exact path (closed-form stick, the fast stick
    recurrence with and without the sensor filter and aging, RK4 slips) against the same force as
    a plug-in force term on the general path (RK4 throughout): slip times within 10 us, peaks
    within 10 mN, Ft within 0.15 N, the bounds tests/model/test_plugin_terms.py holds the two
    paths to for every library effect (their derivation is there)."""
    kp = {"k_N_per_m": 2e5}
    exact = build_model("paper", effects=[*effects, UserFlexure], effect_params={"user_flexure": kp})
    general = build_model("paper", effects=[*effects, ForceTermFlexure],
                          effect_params={"force_term_flexure": kp})
    assert not exact.core_setup().terms.active and general.core_setup().terms.active
    a = Simulator(exact).run(SHS)
    b = Simulator(general).run(SHS)
    assert len(a.events) == len(b.events) >= 3
    assert np.max(np.abs(a.ft_N - b.ft_N)) < 0.15
    for ea, eb in zip(a.events, b.events, strict=True):
        assert ea.t_start_s == pytest.approx(eb.t_start_s, abs=1e-5)
        assert ea.peak_N == pytest.approx(eb.peak_N, abs=0.01)
    base = Simulator(build_model("paper", effects=effects)).run(SHS)
    assert abs(a.events[-1].peak_N - base.events[-1].peak_N) > 1.0  # the spring does act


def test_a_parallel_spring_pulls_the_slider_back_when_the_specimens_part():
    """With the specimens apart (Fn = 0) the spring ties the slider to the frame: it rings about a
    point between the stage and X(0), k_p / (K0 + k_p) of the way back to X(0)."""
    kp = 2e5
    drive = Drive(np.array([0.0, 1.0, 1.01, 3.0]), np.array([0.0, 2e-4, 2e-4, 2e-4]),
                  np.array([300.0, 300.0, 0.0, 0.0]))
    res = _run([UserFlexure], drive, user_flexure={"k_N_per_m": kp})
    k0 = build_model("paper").base_values["k0_N_per_m"]
    want = 2e-4 * k0 / (k0 + kp)
    assert res.x_specimen_m[-1] == pytest.approx(want, rel=1e-3)


class TestUserDragContract(EffectContract):
    effect = UserDrag


class TestUserTiltContract(EffectContract):
    effect = UserTilt


class TestUserFlexureContract(EffectContract):
    effect = UserFlexure
