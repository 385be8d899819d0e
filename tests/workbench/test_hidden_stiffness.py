"""Hidden stiffness effects are named and adding them at least halves the error."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


@pytest.mark.parametrize(("effect", "seed"), [
    ("stress_evolution", 211),
    ("load_dependent_stiffness", 212),
    ("presliding", 214),
])
def test_hidden_stiffness_effect_is_found(effect, seed):
    assert_found(effect, hidden_effect_diagnosis(effect, seed))
