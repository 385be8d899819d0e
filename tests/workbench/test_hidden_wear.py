"""Hidden wear (friction drifting with cumulative slip) is named and at least halves the error."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_hidden_wear_is_found_in_a_long_run():
    assert_found("wear", hidden_effect_diagnosis("wear", 203))
