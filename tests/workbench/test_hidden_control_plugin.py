"""No effect hidden gives `none`; a plug-in effect from a file takes part like a built-in one."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.model.plugins import load_effect_file
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.diagnose import diagnose
from rigctl.workbench.model_choice import ModelChoice
from tests.workbench.hidden import PLUGIN, TEST_BASE

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_control_without_hidden_effect_gives_none():
    runs = simulate_campaign(build_model("paper", params=TEST_BASE), "tlre", seed=231,
                             velocity_m_s=2e-5, duration_scale=0.6)
    diag = diagnose(prepare_dataset(runs), ModelChoice("paper"),
                    candidates=("interface_damping", "probe_drift", "wear", "presliding"),
                    workers=2)
    assert diag.first.verdict.verdict == "none"
    assert not any(s.significant for s in diag.first.ranking)


def test_a_plugin_effect_in_a_file_is_found_and_cuts_the_error(tmp_path):
    path = tmp_path / "my_effects.py"
    path.write_text(PLUGIN)
    (cls,) = load_effect_file(path)
    model = build_model("paper", effects=[cls], params=TEST_BASE,
                        effect_params={"force_sensor_drift": {"rate_N_per_s": 0.03}})
    runs = simulate_campaign(model, "long_run", seed=232, duration_scale=0.5)
    choice = ModelChoice("paper", (), {}, (str(path),))
    diag = diagnose(prepare_dataset(runs), choice,
                    candidates=("force_sensor_drift", "wear", "probe_drift"), workers=2)
    r0 = diag.first
    assert r0.verdict.verdict == "force_sensor_drift"
    top = r0.ranking[0]
    assert top.effect == "force_sensor_drift" and top.error_reduction >= 0.5
