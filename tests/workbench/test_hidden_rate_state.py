"""Hidden rate-and-state friction is named in a slide-hold-slide campaign and halves the error."""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_hidden_rate_state_is_found():
    diag = hidden_effect_diagnosis("rate_state", 201)
    assert_found("rate_state", diag)
