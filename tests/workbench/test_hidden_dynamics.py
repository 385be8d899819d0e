"""Hidden dynamics and measurement-chain effects are named and at least halve the error."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


@pytest.mark.parametrize(("effect", "seed"), [
    ("interface_damping", 221),
    ("sensor_dynamics", 222),
    ("normal_coupling", 223),
])
def test_hidden_dynamics_effect_is_found(effect, seed):
    assert_found(effect, hidden_effect_diagnosis(effect, seed))
