"""A data-informed starting point for identifying the base parameters.

The model is simulated once with its current values; each base parameter is then rescaled by the
ratio of the measured to the simulated feature it mainly sets (paper Sec. 5.2-5.3 relations):

* mu_s by the stable peaks per newton of Fn (peak = mu_s Fn), mu_smax by the first peak;
* mu_s - mu_k by the stress drops per newton (the drop grows with mu_s - mu_k);
* Kts by the stick stiffness K(i) (dFt/d(delta) in stick is the interface stiffness) and Kt0 by the
  first band of the initial-stage curve;
* K0 from the loading rate: in stick dFt/dt = v / (1/K0 + c/Kt), with the compliance coefficient c
  read from the simulation.

Only the parameters being fitted are changed, and all stay within their bounds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigctl.records.dataset import Dataset
from rigctl.records.features import EventTable
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import FreeParam
from rigctl.workbench.model_choice import ModelChoice


def _median(tables: Sequence[EventTable], name: str, stable: bool, per_fn: bool) -> float:
    vals = []
    for ev in tables:
        sel = (ev.stage == 1) if stable else (ev.stage == 0)
        v = ev.features[name][sel]
        if per_fn:
            v = v / np.where(ev.covariates["fn_N"][sel] > 0, ev.covariates["fn_N"][sel], np.nan)
        vals.append(v)
    allv = np.concatenate(vals) if vals else np.zeros(0)
    allv = allv[np.isfinite(allv)]
    return float(np.median(allv)) if allv.size else float("nan")


def _ratio(meas: float, model: float) -> float | None:
    if np.isfinite(meas) and np.isfinite(model) and model != 0 and meas / model > 0:
        return meas / model
    return None


def initial_guess(dataset: Dataset, choice: ModelChoice, free: Sequence[FreeParam],
                  bounded: bool = False, deadline: float | None = None) -> dict[str, float]:
    """The rescaled values (module docstring); ``bounded`` and ``deadline`` bound the model's run
    as :func:`~rigctl.workbench.evaluate.evaluate`'s do."""
    model = evaluate(dataset, choice, bounded=bounded, deadline=deadline).events
    return guess_from_events(dataset, choice, free, model)


def guess_from_events(dataset: Dataset, choice: ModelChoice, free: Sequence[FreeParam],
                      model: Sequence[EventTable]) -> dict[str, float]:
    """:func:`initial_guess` from the slip events ``model`` of ``choice`` already simulated on
    ``dataset`` (one table per run)."""
    values = {p.name: p.value for p in choice.parameter_table()}
    names = {fp.name for fp in free}
    meas = [r.events for r in dataset.runs]
    new = dict(values)
    r_peak = _ratio(_median(meas, "peak_N", True, True), _median(model, "peak_N", True, True))
    r_drop = _ratio(_median(meas, "drop_N", True, True), _median(model, "drop_N", True, True))
    r_first = _ratio(_median(meas, "peak_N", False, True), _median(model, "peak_N", False, True))
    r_k = _ratio(_median(meas, "k_stick_N_per_m", True, False),
                 _median(model, "k_stick_N_per_m", True, False))
    if "mu_s" in names and r_peak:
        new["mu_s"] = values["mu_s"] * r_peak
    if "mu_k" in names and r_drop and "mu_s" in values:
        gap = (values["mu_s"] - values["mu_k"]) * r_drop
        new["mu_k"] = new["mu_s"] - gap
    if "mu_smax" in names and r_first:
        new["mu_smax"] = values["mu_smax"] * r_first
    if "kts_N_per_m" in names and r_k:
        new["kts_N_per_m"] = values["kts_N_per_m"] * r_k
    init_meas = np.nanmedian([ev.init_k_N_per_m[0] for ev in meas]) \
        if any(np.isfinite(ev.init_k_N_per_m[0]) for ev in meas) else np.nan
    init_model = np.nanmedian([ev.init_k_N_per_m[0] for ev in model]) \
        if any(np.isfinite(ev.init_k_N_per_m[0]) for ev in model) else np.nan
    r_init = _ratio(float(init_meas), float(init_model))
    if "kt0_N_per_m" in names and r_init:
        new["kt0_N_per_m"] = values["kt0_N_per_m"] * r_init
    if "k0_N_per_m" in names and "kts_N_per_m" in values:
        new["k0_N_per_m"] = _k0_guess(meas, model, values, new) or values["k0_N_per_m"]
    out = {}
    for fp in free:
        v = new.get(fp.name, values[fp.name])
        if not np.isfinite(v):
            v = values[fp.name]
        out[fp.name] = float(min(max(v, fp.lower), fp.upper))
    return out


def _k0_guess(
    meas: Sequence[EventTable], model: Sequence[EventTable], old: dict[str, float],
    new: dict[str, float],
) -> float | None:
    def keff(tables: Sequence[EventTable]) -> float:
        vals = []
        for ev in tables:
            v = ev.covariates["v_drive_m_per_s"]
            ok = (ev.stage == 1) & (v > 0)
            vals.append(ev.features["rate_N_per_s"][ok] / v[ok])
        allv = np.concatenate(vals) if vals else np.zeros(0)
        allv = allv[np.isfinite(allv)]
        return float(np.median(allv)) if allv.size else float("nan")

    k_meas, k_model = keff(meas), keff(model)
    if not (np.isfinite(k_meas) and np.isfinite(k_model) and k_meas > 0 and k_model > 0):
        return None
    c = (1.0 / k_model - 1.0 / old["k0_N_per_m"]) * old["kts_N_per_m"]
    inv_k0 = 1.0 / k_meas - c / new["kts_N_per_m"]
    if inv_k0 <= 0:
        return old["k0_N_per_m"] * k_meas / k_model
    return 1.0 / inv_k0
