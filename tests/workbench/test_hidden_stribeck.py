"""Hidden Stribeck weakening (velocity steps at two loads): named, and adding it halves the error.

At 300 N the slips run at about 70 mm/s, nine times v_s, so the weakening is over before a slip gets
going and the campaign's 300 N run alone shows only a lower mu_k (base 1.14 -> 0.77 with that run alone).
The same velocity steps at 150 N halve the slip velocity; there the drops fall with v_s in a way no
single mu_k, and no load-dependent mu_k, can follow (rigctl/workbench/campaigns.py).
"""

from __future__ import annotations

import pytest

from tests.workbench.hidden import assert_found, hidden_effect_diagnosis

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_hidden_stribeck_is_found():
    assert_found("stribeck", hidden_effect_diagnosis("stribeck", 204))
