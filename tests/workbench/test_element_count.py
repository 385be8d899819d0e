"""Which models search the element count (rigctl/workbench/element_count.py): those with an effect
that spreads the elements' thresholds."""

from __future__ import annotations

from rigctl.workbench import element_count as ec
from rigctl.workbench.model_choice import ModelChoice


def test_only_an_effect_that_spreads_the_thresholds_asks_for_it():
    assert ec.spreads_elements(ModelChoice("paper", ("presliding",)))
    assert ec.spreads_elements(ModelChoice("paper", ("wear", "presliding")))
    assert not ec.spreads_elements(ModelChoice("paper"))
    assert not ec.spreads_elements(ModelChoice("paper", ("wear", "rate_state")))
