"""Hidden load-dependent friction is named in a force sweep and at least halves the error."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_hidden_load_dependent_friction_is_found_in_a_force_sweep():
    assert_found("load_dependent_friction",
                 hidden_effect_diagnosis("load_dependent_friction", 202))
