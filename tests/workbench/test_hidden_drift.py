"""Hidden slow changes over a long run (contact degradation, probe drift) are told apart."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


@pytest.mark.parametrize(("effect", "seed"), [
    ("contact_degradation", 213),
    ("probe_drift", 224),
])
def test_hidden_drift_effect_is_found(effect, seed):
    assert_found(effect, hidden_effect_diagnosis(effect, seed))
