"""Linear terms of the equations of motion (issue 37 section 1): an effect declares a drag -c V on
the slider and a normal coupling kappa through ``Effect.linear_terms``; the exact path integrates
them in closed form. ``interface_damping`` and ``normal_coupling`` are stated this way (one way, the
same as a plug-in's), and a model with them keeps the exact path."""

from __future__ import annotations

from collections.abc import Mapping
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


class TestUserDragContract(EffectContract):
    effect = UserDrag


class TestUserTiltContract(EffectContract):
    effect = UserTilt
