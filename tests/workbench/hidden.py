"""Hidden-effect cases for the tests: campaigns from the simulator with one effect hidden.

The test conditions differ from the benchmark's (benchmarks/bench_workbench.py): another base
parameter set, 1.5x the effect's typical magnitude, twice the drive velocity, shorter runs, other
seeds. Each case diagnoses with the hidden effect among decoys of similar signature (the full
library is the benchmark's job), so every library effect is exercised in a few seconds.
"""

from __future__ import annotations

import textwrap

from rigctl.model import build_model
from rigctl.model.effects import LIBRARY
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, simulate_campaign
from rigctl.workbench.diagnose import Diagnosis, diagnose
from rigctl.workbench.model_choice import ModelChoice

TEST_BASE = {"mu_s": 0.14, "mu_k": 0.095, "kts_N_per_m": 0.8e6, "k0_N_per_m": 1.6e6,
             "mu_smax": 0.19}
MAGNITUDE = 1.5

DECOYS: dict[str, tuple[str, ...]] = {
    "stress_evolution": ("presliding", "load_dependent_stiffness", "contact_degradation"),
    "stribeck": ("rate_state", "interface_damping", "load_dependent_friction"),
    "rate_state": ("stribeck", "wear", "sensor_dynamics"),
    "load_dependent_friction": ("load_dependent_stiffness", "wear", "normal_coupling"),
    "load_dependent_stiffness": ("load_dependent_friction", "contact_degradation", "presliding"),
    "contact_degradation": ("wear", "probe_drift", "load_dependent_stiffness"),
    "presliding": ("contact_degradation", "sensor_dynamics", "interface_damping"),
    "interface_damping": ("sensor_dynamics", "stribeck", "presliding"),
    "wear": ("contact_degradation", "probe_drift", "load_dependent_friction"),
    "normal_coupling": ("load_dependent_friction", "sensor_dynamics", "probe_drift"),
    "sensor_dynamics": ("interface_damping", "stribeck", "presliding"),
    "probe_drift": ("wear", "contact_degradation", "load_dependent_friction"),
}


def scaled_values(effect: str, magnitude: float) -> dict[str, float]:
    eff = LIBRARY[effect]()
    offs = eff.off_values({"mu_s": TEST_BASE["mu_s"], "kts_N_per_m": TEST_BASE["kts_N_per_m"]})
    return {
        p.name: min(max(offs[p.name] + magnitude * (p.default - offs[p.name]), p.lower), p.upper)
        for p in eff.params if p.identify
    }


def hidden_effect_diagnosis(effect: str, seed: int) -> Diagnosis:
    if effect == "stress_evolution":
        model = build_model("paper", params={**TEST_BASE, **scaled_values(effect, MAGNITUDE)})
        base = "classic"
    else:
        model = build_model("paper", effects=[effect], params=TEST_BASE,
                            effect_params={effect: scaled_values(effect, MAGNITUDE)})
        base = "paper"
    runs = simulate_campaign(model, PROTOCOL_FOR_EFFECT[effect], seed=seed,
                             velocity_m_s=2e-5, duration_scale=0.5)
    # no run limit: a test's verdict must not depend on the machine's load (pytest's timeout
    # catches a hang)
    return diagnose(prepare_dataset(runs), ModelChoice(base),
                    candidates=(effect, *DECOYS[effect]), workers=2, max_run_s=None)


def assert_found(effect: str, diag: Diagnosis) -> None:
    r0 = diag.first
    hidden = next(s for s in r0.ranking if s.effect == effect)
    assert r0.verdict.verdict == effect, [(s.effect, s.error, s.delta_bic) for s in r0.ranking]
    assert hidden.error_reduction >= 0.5, hidden
    assert hidden.significant


# A plug-in effect written to a file by the plug-in tests (CLI and Python API).
PLUGIN = textwrap.dedent('''
    """A force sensor whose zero drifts linearly in time (thermal drift of the bridge)."""
    from rigctl.model import Effect, ParamSpec


    class ForceSensorDrift(Effect):
        name = "force_sensor_drift"
        summary = "the force sensor's zero drifts linearly with time"
        signature = "peaks and troughs drift with time while stick times stay"
        reveal_protocol = "a long hold at zero tangential load recording Ft"
        params = (ParamSpec("rate_N_per_s", 0.01, -1.0, 1.0, "N/s", "zero drift rate", off=0.0),)

        def transform_output(self, result, values):
            result.ft_N += values["rate_N_per_s"] * (result.t_s - result.t_s[0])
''')
