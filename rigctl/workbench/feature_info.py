"""What each compared feature is: unit, how residuals are formed, and how it is named in words."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FeatureInfo:
    name: str
    unit: str
    log: bool
    """Residuals as ln(model / measured) (positive scale-like features) instead of differences."""
    phrase: str
    """Plural noun phrase for explanations ("peaks")."""
    floor_kind: str
    """What the scatter floor is relative to: 'drop', 'slip', 'relative' or 'unit'."""
    phase_sensitive: bool = False
    """Depends on where the samples fall within a sub-millisecond slip: its scatter is the total
    spread of the measured values, not the successive-difference one (two records a fraction of a
    sample apart in slip timing give unrelated values)."""


FEATURES: dict[str, FeatureInfo] = {
    f.name: f
    for f in (
        FeatureInfo("peak_N", "N", False, "peaks", "drop"),
        FeatureInfo("trough_N", "N", False, "troughs (settled post-slip levels)", "drop"),
        FeatureInfo("drop_N", "N", False, "stress drops", "drop"),
        FeatureInfo("stick_s", "s", True, "stick durations (recurrence)", "relative"),
        FeatureInfo("rate_N_per_s", "N/s", True, "stick loading rates", "relative"),
        FeatureInfo("k_stick_N_per_m", "N/m", True, "stick stiffnesses K(i)", "relative"),
        FeatureInfo("rounding", "-", False, "stick-ramp end slopes (rounding before the peak)",
                    "unit"),
        FeatureInfo("ring_N", "N", False, "post-slip ringing amplitudes", "drop", True),
        FeatureInfo("step_frac", "-", False, "drop sharpnesses", "unit", True),
        FeatureInfo("slip_m", "m", False, "slip distances", "slip"),
        FeatureInfo("fn_swing_N", "N", False, "normal-force swings at slips", "drop"),
        FeatureInfo("lag_m", "m", False, "probe readings delta relative to the stage (lag)", "slip"),
        FeatureInfo("init_k_N_per_m", "N/m", True, "initial-stage stiffnesses", "relative"),
    )
}

FLOOR_FRACTION = 0.005
"""Scatter floor: 0.5 % of the feature's scale, so noise-free data do not get infinite weight."""

INIT_FLOOR = 0.02
"""Relative scatter assumed for the initial-stage stiffness bands (one curve per run, no repeats)."""

UNIT_FLOOR = 0.01
"""Scatter floor of dimensionless ratios."""

PHASE_FLOOR_FRACTION = 0.15
"""Scatter floor of phase-sensitive features: 15 % of their median value. Where the samples fall
within a sub-millisecond slip changes them by this much from slip to slip even in a perfect model,
so differences below it are not evidence."""
