"""What each compared feature is: unit, how residuals are formed, and how it is named in words."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FeatureInfo:
    """One compared feature. The order of :data:`FEATURES` is the order of the residual vector."""

    name: str
    unit: str
    log: bool
    """Residuals as ln(model / measured) (positive scale-like features) instead of differences."""
    phrase: str
    """Plural noun phrase for explanations ("peaks")."""
    floor_kind: str
    """What the scatter floor is relative to: 'drop', 'slip', 'relative', 'unit' or 'sample' (the
    sample interval)."""
    phase_sensitive: bool = False
    """Depends on where the samples fall within a sub-millisecond slip: its scatter is the total
    spread of the measured values, not the successive-difference one (two records a fraction of a
    sample apart in slip timing give unrelated values)."""
    per_event: bool = True
    """Read once per stick-slip cycle (an :class:`~rigctl.records.features.EventTable` column);
    False for the initial-stage curve, read once per run."""
    from_slope: bool = False
    """Read from a fitted slope, whose per-event standard error the event table keeps."""
    zero_free: bool = False
    """Has no zero of its own in a run (a probe's zero is arbitrary): compared up to a constant, each
    side's values about their median over the run's paired events
    (:func:`rigctl.workbench.metrics.compare_run`)."""
    from_images: bool = False
    """Read from the run file's camera frames (:mod:`rigctl.records.image_features`), once per
    run; a run without frames has none."""


FEATURES: dict[str, FeatureInfo] = {
    f.name: f
    for f in (
        FeatureInfo("peak_N", "N", log=False, phrase="peaks", floor_kind="drop"),
        FeatureInfo("trough_N", "N", log=False, phrase="troughs (settled post-slip levels)",
                    floor_kind="drop"),
        FeatureInfo("drop_N", "N", log=False, phrase="stress drops", floor_kind="drop"),
        FeatureInfo("stick_s", "s", log=True, phrase="stick durations (recurrence)",
                    floor_kind="relative"),
        FeatureInfo("rate_N_per_s", "N/s", log=True, phrase="stick loading rates",
                    floor_kind="relative", from_slope=True),
        FeatureInfo("k_stick_N_per_m", "N/m", log=True, phrase="stick stiffnesses K(i)",
                    floor_kind="relative", from_slope=True),
        FeatureInfo("rounding", "-", log=False,
                    phrase="stick-ramp end slopes (rounding before the peak)", floor_kind="unit",
                    from_slope=True),
        FeatureInfo("ring_N", "N", log=False, phrase="post-slip ringing amplitudes",
                    floor_kind="drop", phase_sensitive=True),
        FeatureInfo("step_frac", "-", log=False, phrase="drop sharpnesses", floor_kind="unit",
                    phase_sensitive=True),
        FeatureInfo("slip_m", "m", log=False, phrase="slip distances", floor_kind="slip"),
        FeatureInfo("drop_delay_s", "s", log=False,
                    phrase="drop delays behind the probes' slip",
                    floor_kind="sample"),
        FeatureInfo("fn_swing_N", "N", log=False, phrase="normal-force swings at slips",
                    floor_kind="drop"),
        FeatureInfo("lag_m", "m", log=False,
                    phrase="probe readings delta relative to the stage (lag)", floor_kind="slip",
                    zero_free=True),
        FeatureInfo("init_k_N_per_m", "N/m", log=True, phrase="initial-stage stiffnesses",
                    floor_kind="relative", per_event=False),
        FeatureInfo("p_tilt_initial", "-", log=False,
                    phrase="initial-stage stress tilts (P_linear slope, from the contact images)",
                    floor_kind="unit", per_event=False, from_images=True),
        FeatureInfo("p_var_stable", "-", log=False,
                    phrase="stable-stage changes of the back-end stress share (contact images)",
                    floor_kind="unit", per_event=False, from_images=True),
    )
}

EVENT_FEATURES: tuple[str, ...] = tuple(n for n, f in FEATURES.items() if f.per_event)
"""The per-cycle features, in the order of the residual vector."""
SE_FEATURES: tuple[str, ...] = tuple(n for n, f in FEATURES.items() if f.from_slope)
"""Features read from a fitted slope, whose per-event standard error the event table keeps."""
IMAGE_FEATURES: tuple[str, ...] = tuple(n for n, f in FEATURES.items() if f.from_images)
"""Features read from the contact images (after the initial-stage curve in the residual vector)."""

FLOOR_FRACTION = 0.005
"""Scatter floor: 0.5 % of the feature's scale, so noise-free data do not get infinite weight."""

INIT_FLOOR = 0.02
"""Relative scatter assumed for the initial-stage stiffness bands (one curve per run, no repeats)."""

UNIT_FLOOR = 0.01
"""Scatter floor of dimensionless ratios."""

SAMPLE_FLOOR = 0.5
"""Scatter floor of times read between two channels' samples (``drop_delay_s``): half a sample
interval. Each crossing is interpolated between two samples; where the fall is not resolved (over
one or two samples) the interpolation is all there is, and a difference below it is not evidence."""

PHASE_FLOOR_FRACTION = 0.15
"""Scatter floor of phase-sensitive features: 15 % of their median value. Where the samples fall
within a sub-millisecond slip changes them by this much from slip to slip even in a perfect model,
so differences below it are not evidence."""
