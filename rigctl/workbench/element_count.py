"""The element count N of a model whose effects spread the elements' static thresholds.

N, the number of Jenkins elements the contact is cut into (paper Sec. 5.1), is an integer no
least-squares step moves, and another rig's data do not state it. The paper model alone hardly
tells N apart: on held-out seed 4 case 7 (generated with N = 39) the base fit scores 40.5, 40.4
and 40.8 at N = 10, 20 and 40. An effect that spreads the thresholds over the elements
(``presliding``: :meth:`rigctl.model.effects.base.Effect.element_threshold_factors`) makes the
stick ramp round off in N steps, and there N matters: ``presliding`` alone scores 4.98 at N = 10
and 3.48 at N = 20, with ``contact_degradation`` as well 3.83 and 1.39. So once such an effect is
in the model, the model is refitted at each count of :data:`ELEMENT_COUNTS` and the best kept.
"""

from __future__ import annotations

from collections.abc import Callable

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.model.effects import Effect
from rigctl.workbench.dataset import Dataset
from rigctl.workbench.identify import FitResult, free_params, least_squares_fit
from rigctl.workbench.model_choice import ModelChoice, effect_class

ELEMENT_COUNTS: tuple[int, ...] = (5, 10, 20, 40)
"""Counts tried (a factor 2 apart: the rounding changes little for smaller steps)."""
MIN_GAIN = 0.1
"""Another count is taken only where it removes at least this fraction of the error: it gets
``max_nfev`` more evaluations than the model it is compared with, which alone gains a little."""
MAX_NFEV = 12
"""Least-squares evaluations of the refit at each count."""


def spreads_elements(choice: ModelChoice) -> bool:
    """Some effect of ``choice`` scales the elements' thresholds one by one."""
    for name in choice.effects:
        cls = effect_class(name, choice.effect_files)
        if cls is not None and \
                cls.element_threshold_factors is not Effect.element_threshold_factors:
            return True
    return False


def best_element_count(
    dataset: Dataset, result: FitResult, say: Callable[[str], None] = lambda _m: None,
    max_nfev: int = MAX_NFEV,
) -> FitResult:
    """``result`` refitted at the element count that fits best, or ``result`` itself where no
    effect spreads the thresholds, the rig description fixes N, or no count gains MIN_GAIN."""
    if "n_elements" in dataset.rig.fixed or not spreads_elements(result.choice):
        return result
    n_now = result.choice.build().n_elements
    free = free_params(result.choice, list(result.free))
    best = result
    for n in ELEMENT_COUNTS:
        if n == n_now:
            continue
        try:
            fit = least_squares_fit(dataset, result.choice.with_values({"n_elements": n}), free,
                                    max_nfev=max_nfev)
        except (ParameterError, SimulationError) as exc:
            say(f"  N = {n} elements: no fit ({exc})")
            continue
        say(f"  N = {n} elements: error {fit.error:.3g} (N = {n_now}: {result.error:.3g})")
        if fit.misses_most_slips or not fit.error < (1.0 - MIN_GAIN) * best.error:
            continue
        best = fit
    return best
