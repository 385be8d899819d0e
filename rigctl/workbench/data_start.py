"""The data-scale start: a model's base values at the campaign's own scale, read from its events.

What the measured events and the post-slip ringing show directly (:mod:`rigctl.workbench.
data_scale`: friction levels, stiffness, mass and damping) set as the model's base values within
their bounds, the search's start on another rig's data (:mod:`rigctl.workbench.search`).
"""

from __future__ import annotations

from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.workbench.data_scale import DataScale, base_start, measure_scale
from rigctl.workbench.identify import FreeParam
from rigctl.workbench.model_choice import ModelChoice


def campaign_scale(dataset: Dataset) -> DataScale:
    """What the campaign's measured events and post-slip ringing show directly (data_scale.py)."""
    return measure_scale(
        (r.events for r in dataset.runs),
        delta_measured=any(r.delta_measured for r in dataset.runs),
        ringing=dataset.ringing,
    )


def data_scaled(dataset: Dataset, choice: ModelChoice,
                free: list[FreeParam]) -> ModelChoice | None:
    """``choice`` with its base values at the data's scale (None when the events do not show it).

    Fitted parameters take the data-scale values within their (rig-description) bounds; the fixed
    ones keep what the rig description states."""
    current = {p.name: p.value for p in choice.parameter_table()}
    scale = campaign_scale(dataset)
    values = base_start(scale, current, dataset.rig.fixed)
    if not values:
        return None
    bounds = {fp.name: (fp.lower, fp.upper) for fp in free}
    table = {p.name: p for p in choice.parameter_table()}
    out = {}
    for k, v in values.items():
        lo, hi = bounds.get(k, (table[k].lower, table[k].upper))
        out[k] = float(min(max(v, lo), hi))
    if out.get("mu_k", 0.0) >= out.get("mu_s", 1.0):
        return None
    try:
        return choice.with_values(out)
    except ParameterError:
        return None
