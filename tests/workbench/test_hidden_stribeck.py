"""Hidden Stribeck weakening (velocity steps): named, but cannot halve the error here (reason)."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis


@pytest.mark.xfail(strict=True, reason=(
    "signature at the noise floor in this campaign: diagnose names stribeck (delta BIC -19, "
    "significant); the base model already scores 1.14 (E ~ 1 is 'within the scatter') and "
    "base + stribeck 0.77, a 32 % cut. The generating parameters score 0.45 only at exactly "
    "their values (the model then repeats the data's sampling phase); 0.1-0.6 % off in v_s or "
    "mu_k they score 0.73-1.29, so no fit can halve 1.14. In this engine Stribeck acts on the "
    "slip velocity (mm/s), not on drive velocities of 10-100 um/s: a velocity-step campaign "
    "barely shows it at 1024 Hz"))
def test_hidden_stribeck_is_found():
    assert_found("stribeck", hidden_effect_diagnosis("stribeck", 204))
