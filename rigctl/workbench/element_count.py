"""The element count N of a model whose effects spread the elements' static thresholds.

N, the number of Jenkins elements the contact is cut into (paper Sec. 5.1), is an integer no
least-squares step moves, and another rig's data do not state it. The paper model alone hardly
tells N apart: in its stable stage all elements reach their threshold together (uniform P,
docs/model.md), so N shows only in the steps of the initial stage. An effect that spreads the
thresholds over the elements (``presliding``:
:meth:`rigctl.model.effects.base.Effect.element_threshold_factors`) makes every stick ramp round
off in N steps, one per element reaching its own threshold, and there N shapes every ramp (the
figures that showed both: docs/decisions.md). So where such an effect is in the model, log2 N is
a coordinate of the one search (:mod:`rigctl.workbench.search_space`), searched by its global
stage like any other and rounded where the model is built.
"""

from __future__ import annotations

from rigctl.model.effects import Effect
from rigctl.workbench.model_choice import ModelChoice, effect_class


def spreads_elements(choice: ModelChoice) -> bool:
    """Some effect of ``choice`` scales the elements' thresholds one by one."""
    for name in choice.effects:
        cls = effect_class(name, choice.effect_files)
        if cls is not None and \
                cls.element_threshold_factors is not Effect.element_threshold_factors:
            return True
    return False
