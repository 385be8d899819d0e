"""Physical validity: each effect states its own rule (Effect.invalid_reason), the model combines
them with the friction laws (ModelSpec.invalid_reason), and the workbench asks the model."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pytest

from rigctl.model import CoreParams, Drive, Effect, ParamSpec, Simulator, build_model
from rigctl.workbench.identify import physically_valid
from rigctl.workbench.model_choice import ModelChoice


def test_library_defaults_are_valid():
    assert build_model("paper").invalid_reason((150.0, 450.0)) is None
    assert build_model("paper", effects=["wear", "load_dependent_friction"]).invalid_reason() is None


@pytest.mark.parametrize(("kwargs", "named"), [
    ({"params": {"mu_k": 0.16}}, "mu_s"),  # kinetic above static
    ({"params": {"mu_k": 0.12, "mu_smax": 0.12}}, "mu_smax"),  # stress_evolution's own rule
    ({"effects": ["wear"], "effect_params": {"wear": {"dmu_s": -0.05, "dmu_k": 0.0}}}, "wear"),
])
def test_each_rule_names_what_breaks_it(kwargs, named):
    reason = build_model("paper", **kwargs).invalid_reason()
    assert reason is not None and named in reason and "\n" not in reason


def test_the_friction_laws_are_checked_over_the_normal_force_range():
    # mu_k grows faster with Fn than mu_s: fine at 300 N, kinetic above static at 800 N
    model = build_model("classic", effects=["load_dependent_friction"],
                        effect_params={"load_dependent_friction": {"alpha_s": 0.0, "alpha_k": 1.0}})
    assert model.invalid_reason((300.0, 300.0)) is None
    reason = model.invalid_reason((300.0, 800.0))
    assert reason is not None and "800" in reason


class _Softening(Effect):
    """A plug-in with its own rule: mu_k scaled by a factor that must stay below mu_s / mu_k."""

    name = "softening_plugin"
    summary = "scales mu_k"
    signature = "troughs"
    reveal_protocol = "TLRE"
    params = (ParamSpec("factor", 1.1, 0.5, 3.0, "-", "mu_k multiplier", off=1.0),)

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["mu_k"] = core["mu_k"] * values["factor"]

    def invalid_reason(self, values: Mapping[str, float], base: Mapping[str, float]) -> str | None:
        if base["mu_k"] * values["factor"] >= base["mu_s"]:
            return "softening_plugin: factor lifts mu_k to mu_s"
        return None


def test_a_plugin_states_its_own_rule_and_the_workbench_follows_it():
    ok = build_model("paper", effects=[_Softening])
    bad = ok.with_values({"softening_plugin.factor": 2.0})
    assert ok.invalid_reason() is None
    assert bad.invalid_reason() == "softening_plugin: factor lifts mu_k to mu_s"


BROKEN_PLUGIN = """
from rigctl.model import Effect, ParamSpec


class Broken(Effect):
    name = "broken_plugin"
    summary = "a hook with a programming error"
    signature = "none"
    reveal_protocol = "none"
    params = (ParamSpec("x", 1.0, 0.0, 2.0, "-", "unused", off=0.0),)

    def apply(self, core, values):
        core["mu_k"] = core["mu_k"] + None
"""


def test_physically_valid_asks_the_model_and_lets_programming_errors_through(tmp_path):
    assert physically_valid(ModelChoice("paper", (), {"mu_k": 0.1}), (250.0, 450.0))
    assert not physically_valid(ModelChoice("paper", (), {"mu_k": 0.16}), (250.0, 450.0))
    path = tmp_path / "broken.py"
    path.write_text(BROKEN_PLUGIN)
    choice = ModelChoice("paper", ("broken_plugin",), effect_files=(str(path),))
    with pytest.raises(TypeError):  # a bug, not an invalid point: it must not be swallowed
        physically_valid(choice, (250.0, 450.0))


def test_the_stribeck_part_is_not_held_against_the_initial_stage():
    """With ``stribeck`` the kinetic friction at V = 0 is the stable stage's mu_s; where
    ``load_dependent_friction`` raises mu_s with the load above the initial stage's mu_s,max, that
    is no reason to refuse the model (the kernel caps the Stribeck part by what the elements carry,
    and the engine runs it with its slips). Kinetic friction without it above mu_s,max still is."""
    rising = {"load_dependent_friction": {"alpha_s": 0.4, "alpha_k": 0.4, "fn_ref_N": 300.0}}
    model = build_model("paper", effects=["load_dependent_friction", "stribeck"],
                        params={"mu_s": 0.15, "mu_smax": 0.16}, effect_params=rising)
    assert model.invalid_reason((150.0, 600.0)) is None  # mu_s(600 N) = 0.198 > mu_smax
    res = Simulator(model, sample_rate_hz=1024.0).run(Drive.constant(600.0, 2e-4, 3.0),
                                                      record_elements=False)
    assert np.all(np.isfinite(res.ft_N)) and res.ft_N.max() > 0.15 * 600.0
    assert res.ft_N[-512:].min() < 0.9 * res.ft_N[-512:].max()  # still stick-slip
    # mu_k(600 N) = 0.12 x 2^0.5 = 0.170: below the stable stage's 0.198, above mu_s,max 0.16
    too_high = model.with_values({"mu_k": 0.12, "load_dependent_friction.alpha_k": 0.5})
    reason = too_high.invalid_reason((150.0, 600.0))
    assert reason is not None and "initial" in reason
