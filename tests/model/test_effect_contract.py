"""Every built-in effect passes rigctl.testing.EffectContract, the contract shipped to plug-in authors;
and the contract catches effects that break it."""

from __future__ import annotations

from collections.abc import Mapping

import pytest

from rigctl.model import LIBRARY, CoreParams, Effect, ParamSpec
from rigctl.model.effects import (
    ContactDegradation,
    InterfaceDamping,
    LoadDependentFriction,
    LoadDependentStiffness,
    NormalCoupling,
    Presliding,
    ProbeDrift,
    RateState,
    SensorDynamics,
    StressEvolution,
    Stribeck,
    Wear,
)
from rigctl.testing import EffectContract


class TestStressEvolution(EffectContract):
    effect = StressEvolution
    base = "classic"  # part of the paper base


class TestStribeck(EffectContract):
    effect = Stribeck


class TestRateState(EffectContract):
    effect = RateState


class TestLoadDependentFriction(EffectContract):
    effect = LoadDependentFriction


class TestLoadDependentStiffness(EffectContract):
    effect = LoadDependentStiffness


class TestContactDegradation(EffectContract):
    effect = ContactDegradation


class TestPresliding(EffectContract):
    effect = Presliding


class TestInterfaceDamping(EffectContract):
    effect = InterfaceDamping


class TestWear(EffectContract):
    effect = Wear


class TestNormalCoupling(EffectContract):
    effect = NormalCoupling


class TestSensorDynamics(EffectContract):
    effect = SensorDynamics


class TestProbeDrift(EffectContract):
    effect = ProbeDrift


def test_every_library_effect_has_a_contract_test():
    tested = {cls.effect for cls in EffectContract.__subclasses__()
              if cls.__module__ == __name__}
    assert tested == set(LIBRARY.values())


# --- the contract fails effects that break the rules ----------------------------------------------

class _LeakyOff(Effect):
    """Off value that still changes the model: kt_multiplier = 1 + x, x's off is 0.1 (wrong)."""

    name = "leaky_off"
    summary = "stiffness offset"
    signature = "stick slopes"
    reveal_protocol = "TLRE"
    params = (ParamSpec("x", 0.3, 0.0, 1.0, "-", "stiffness excess", off=0.1),)

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["kt_multiplier"] = 1.0 + values["x"]


class _Stateful(Effect):
    """Counts slips on the instance: a second run of the same model differs from the first."""

    name = "stateful"
    summary = "friction that remembers earlier runs"
    signature = "peaks differ between identical runs"
    reveal_protocol = "TLRE"
    params = (ParamSpec("step", 0.001, 0.0, 0.01, "-", "mu_s step per slip", off=0.0),)

    def __init__(self) -> None:
        self.count = 0

    def on_slip_end(self, core: CoreParams, values: Mapping[str, float], ctx) -> None:
        self.count += 1
        core["dmu_s"] = values["step"] * self.count


class _Unbounded(Effect):
    """Does nothing at all, even at its defaults."""

    name = "does_nothing"
    summary = "nothing"
    signature = "none"
    reveal_protocol = "any"
    params = (ParamSpec("x", 0.5, 0.0, 1.0, "-", "unused", off=0.0),)


@pytest.mark.parametrize(("effect", "test", "message"), [
    (_LeakyOff, "test_off_values_reduce_the_model_exactly_to_the_base", "at its off values"),
    (_Stateful, "test_runs_are_deterministic_and_keep_no_state_on_the_instance", "differ"),
    (_Unbounded, "test_default_values_change_the_model", "leaves every output unchanged"),
])
def test_the_contract_catches_a_broken_effect(effect, test, message):
    contract = type("Contract", (EffectContract,), {"effect": effect})()
    with pytest.raises(AssertionError, match=message):
        getattr(contract, test)()
