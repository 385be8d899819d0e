"""The data's own scale: starting values of a model of another rig, read from the record alone.

The model's preset is this rig (paper Sec. 5.3: Fn = 300 N, K0 = 1.475e6 N/m, M = 0.048 kg). A
record of another rig (a spring-slider at a fraction of a newton on a spring of some hundred N/m, a
tribometer at a few newtons, a rock biax at MPa) lies decades away, and a local fit started at the
preset never leaves it. So before any fit
the base parameters are set from what the measured events show directly (no simulation):

* **friction levels** from the stable peaks and troughs over Fn. A slip from rest at mu_s Fn with
  little damping overshoots below the kinetic level as far as it started above it (a released
  spring-mass on Coulomb friction: trough = 2 mu_k Fn - mu_s Fn), so
  ``mu_s = peak / Fn`` and ``mu_k = (peak + trough) / (2 Fn)``; the initial-stage threshold
  ``mu_smax`` from the first peak.
* **stiffness** from the stick: the loading rate against the drive, ``K_eff = dFt/dx_stage``
  (= rate / drive velocity), is the series stiffness ``1 / (1/K0 + 1/Kts)`` of drive and interface
  (paper Sec. 5.2: both carry Ft in stick). Where delta is measured, dFt/d(delta) in stick is Kts
  and K0 follows; without delta the two are not separable and keep the preset's ratio Kts/K0 (the
  fit reports them as not determined). Where no stick's loading ramp is read (sticks too short
  for its 10-60 % window) but delta is measured, the slips show K0 instead: during a global slip
  every element slides at its kinetic level, so only the drive spring changes its force, and
  ``Ft = K0 (x_stage - X)`` (docs/model.md, section 1) gives ``drop = K0 (slip - v T_slip)``,
  about ``K0 slip`` while the stage barely moves during the slip; ``K_eff`` is then the series of
  that K0 and an interface at the preset's ratio Kts/K0.
* **mass and damping** from a rig description (``m_kg``, ``c0_N_s_per_m``) where given; else from
  the post-slip ringing where the sampling resolves it (:mod:`rigctl.records.ringing`): in stick
  the mass rings between drive spring and interface, ``M = (K0 + Kts) / omega_n^2``, and decays at
  ``sigma = C0 / (2 M)``, so ``C0 = 2 sigma M``; else the mass keeps the preset's slip frequency
  sqrt(K0/M) (during a global slip every element slides and the mass swings on the drive spring
  alone: 880 Hz, a slip over in about half a millisecond, under one sample at most rates) and C0
  the preset's damping ratio C0 / (2 sqrt(K0 M)) (0.75 %).

Effect parameters that declare what they scale with (``ParamSpec.scales_with``) are carried to the
data's scale by the ratio of that quantity, data over preset (:func:`scale_ratios`,
:func:`scale_effect_values`): a reference load by the normal force, a reference velocity by the
drive velocity, a Stribeck velocity by the slip velocity drop / sqrt(K0 M), a characteristic length
by the slip distance drop / K_eff, a contact age by the stick time, a sensor time constant by the
sample interval, a damping coefficient by sqrt(K0 M). A ratio within [1/3, 3] of the preset is left
alone: there the preset's own defaults are the better prior.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from rigctl.model.params import BASE_PARAMS
from rigctl.records.features import EventTable
from rigctl.records.ringing import Ringing, ringing_mass

PRESET = {s.name: float(s.default) for s in BASE_PARAMS}
PRESET_FN_N = 300.0
"""The preset's normal force (paper Sec. 5.3)."""
PRESET_V_M_PER_S = 1e-5
"""The preset's drive velocity (paper Sec. 5.3)."""
PRESET_SAMPLE_RATE_HZ = 1024.0
"""This rig's DAQ rate (the preset's sensor time constant is three of its samples)."""
PRESET_KT0_N_PER_M = 1.5e6
PRESET_KTS_RATIO = PRESET["kts_N_per_m"] / PRESET["k0_N_per_m"]
"""The preset's Kts / K0, kept where the data do not separate the two stiffnesses."""
NEAR_PRESET = 3.0
"""A data scale within this factor of the preset's leaves the preset's effect defaults alone."""
RESOLVED_FRACTION = 0.5
"""Share of stick windows with a positive delta-on-Ft slope needed to read dFt/d(delta)."""
STIFF_CAP = 1e3
"""An interface stiffer than this many times the series stiffness is taken as this (rigid)."""
MIN_GAP = 1e-3
"""mu_k stays at least this fraction below mu_s (the model needs mu_k < mu_s to stick-slip)."""


def _finite(values: Iterable[np.ndarray]) -> np.ndarray:
    arrs = [np.asarray(v, dtype=float).ravel() for v in values]
    allv = np.concatenate(arrs) if arrs else np.zeros(0)
    return allv[np.isfinite(allv)]


def _median(values: Iterable[np.ndarray]) -> float:
    v = _finite(values)
    return float(np.median(v)) if v.size else math.nan


@dataclass(frozen=True)
class DataScale:
    """What the measured events show directly (SI units; NaN where the data do not show it)."""

    fn_N: float
    """Median normal force at the slips."""
    v_m_per_s: float
    """Median drive speed at the slips."""
    mu_peak: float
    """Median stable-stage peak / Fn."""
    mu_trough: float
    """Median stable-stage trough / Fn."""
    mu_first: float
    """Median initial-stage peak / Fn (NaN without an initial stage)."""
    k_eff_N_per_m: float
    """Median stick loading stiffness dFt/dx_stage (stable stage); where no loading ramp is read,
    the series stiffness implied by the slips' K0 (:func:`slip_k0`)."""
    k_stick_N_per_m: float
    """Median dFt/d(delta) in stick (NaN where delta was not measured or does not resolve it)."""
    stick_s: float
    """Median stick duration."""
    delta_measured: bool = True
    """False when no run of the campaign has a displacement probe."""
    ringing: Ringing = field(default_factory=Ringing)
    """The campaign's post-slip ringing (not resolved: NaN frequency)."""

    @property
    def usable(self) -> bool:
        return all(math.isfinite(v) and v > 0 for v in (self.fn_N, self.mu_peak, self.k_eff_N_per_m))


def split_guessed(scale: DataScale) -> tuple[float, float] | None:
    """The plausible interval of the stiffness ratio Kts / K0 where delta is measured but does not
    resolve the interface's give in stick (``k_stick_N_per_m`` +inf), else None.

    The split of the series stiffness K_eff between drive spring and interface is then a guess of
    :func:`base_start` (a rigid interface, STIFF_CAP times K_eff), not a reading, while the delta
    features (the slips' jumps and lags of delta) still tell one split from another; the search
    spreads it (:func:`rigctl.workbench.search_space.build_space`). Either stiffness may be the
    softer, by up to STIFF_CAP, the ratio at which ``base_start`` takes the stiffer one as rigid:
    ``(1 / STIFF_CAP, STIFF_CAP)``. An unresolved give does not make the interface the stiffer:
    the probes' noise and the share of resolved stick windows (RESOLVED_FRACTION) decide it as
    much as the give does. K_eff itself is read from the loading ramps (paper Sec. 5.2).

    Without delta no feature reads the interface's give (the split shows only in the slips'
    dynamics, and the fit reports the two stiffnesses as not determined): the preset's ratio is
    kept and not spread, as a spread over a direction the data hardly tell apart adds only the
    variance of its draws."""
    if not scale.usable or not scale.delta_measured or not math.isinf(scale.k_stick_N_per_m):
        return None
    return (1.0 / STIFF_CAP, STIFF_CAP)


def measure_scale(tables: Iterable[EventTable], delta_measured: bool = True,
                  ringing: Ringing | None = None) -> DataScale:
    """The :class:`DataScale` of the measured events of a campaign (``ringing``: its post-slip
    ringing, :func:`rigctl.records.ringing.campaign_ringing`).

    dFt/d(delta) is read only where delta resolves the interface's give in stick: the stick
    windows' delta-on-Ft slopes (compliances) must come out positive in at least
    RESOLVED_FRACTION of the sticks; where delta barely moves in stick its noise gives either
    sign, the interface is rigid at the probe's resolution and ``k_stick_N_per_m`` is +inf.
    """
    tabs = list(tables)

    def col(name: str, stable: bool | None, per_fn: bool = False) -> list[np.ndarray]:
        out = []
        for ev in tabs:
            sel = np.ones(ev.n, dtype=bool) if stable is None else (ev.stage == (1 if stable else 0))
            v = np.abs(ev.features[name][sel])
            if per_fn:
                fn = ev.covariates["fn_N"][sel]
                v = v / np.where(fn > 0, fn, np.nan)
            out.append(v)
        return out

    rates = []
    for ev in tabs:
        v = np.abs(ev.covariates["v_drive_m_per_s"])
        ok = (ev.stage == 1) & (v > 0)
        rates.append(np.abs(ev.features["rate_N_per_s"][ok]) / v[ok])
    k_stick = math.nan
    if delta_measured:
        n_rate = sum(int(np.isfinite(ev.features["rate_N_per_s"][ev.stage == 1]).sum())
                     for ev in tabs)
        n_k = sum(int(np.isfinite(ev.features["k_stick_N_per_m"][ev.stage == 1]).sum())
                  for ev in tabs)
        if n_rate and n_k >= RESOLVED_FRACTION * n_rate:
            k_stick = _median(col("k_stick_N_per_m", True))
        elif n_rate:
            k_stick = math.inf
    k_eff = _median(rates)
    if not math.isfinite(k_eff) and delta_measured:
        k0 = slip_k0(tabs)  # in series with Kts = PRESET_KTS_RATIO K0 (NaN stays NaN)
        k_eff = k0 * PRESET_KTS_RATIO / (1.0 + PRESET_KTS_RATIO)
    speeds = [np.abs(ev.covariates["v_drive_m_per_s"]) for ev in tabs]
    speeds = [s[s > 0] for s in speeds]
    return DataScale(
        fn_N=_median(ev.covariates["fn_N"] for ev in tabs),
        v_m_per_s=_median(speeds),
        mu_peak=_median(col("peak_N", True, per_fn=True)),
        mu_trough=_median(col("trough_N", True, per_fn=True)),
        mu_first=_median(col("peak_N", False, per_fn=True)),
        k_eff_N_per_m=k_eff,
        k_stick_N_per_m=k_stick,
        stick_s=_median(col("stick_s", True)),
        delta_measured=delta_measured,
        ringing=ringing or Ringing(),
    )


def slip_k0(tables: Iterable[EventTable]) -> float:
    """The drive spring K0 the stable slips show: the median of each slip's force drop over its
    slip distance (``drop = K0 slip`` while every element slides and the stage barely moves,
    module docstring). It reads low by the stage's travel during the slip, ``v T_slip`` against the
    slip, which is small in stick-slip. NaN where no stable slip has both (no delta measured)."""
    ratios = []
    for ev in tables:
        sel = ev.stage == 1
        drop = np.abs(ev.features["drop_N"][sel])
        slip = np.abs(ev.features["slip_m"][sel])
        ok = np.isfinite(drop) & np.isfinite(slip) & (slip > 0) & (drop > 0)
        ratios.append(drop[ok] / slip[ok])
    return _median(ratios)


def base_start(scale: DataScale, current: Mapping[str, float],
               fixed: Mapping[str, float] | None = None) -> dict[str, float]:
    """Base (and stress-evolution) values at the data's scale (see the module docstring).

    ``current`` holds the model's values (names as in its parameter table); ``fixed`` the values a
    rig description states, which are kept as given. Only names present in ``current`` are returned.
    """
    fixed = dict(fixed or {})
    out: dict[str, float] = {}
    if not scale.usable:
        return out
    mu_s = scale.mu_peak
    if math.isfinite(scale.mu_trough):
        mu_k = min(max(0.5 * (scale.mu_peak + scale.mu_trough), 0.0), mu_s * (1.0 - MIN_GAP))
    else:
        mu_k = mu_s * PRESET["mu_k"] / PRESET["mu_s"]  # no trough read: the preset's ratio
    out["mu_s"], out["mu_k"] = mu_s, mu_k
    if "mu_smax" in current:
        first = scale.mu_first if math.isfinite(scale.mu_first) else mu_s
        out["mu_smax"] = max(first, mu_s)
    # stiffness split: K_eff = 1 / (1/K0 + 1/Kts)
    k_eff = scale.k_eff_N_per_m
    k0 = fixed.get("k0_N_per_m", math.nan)
    kts = fixed.get("kts_N_per_m", math.nan)
    if math.isfinite(k0) and not math.isfinite(kts):
        inv = 1.0 / k_eff - 1.0 / k0
        kts = 1.0 / inv if inv > 0 else 100.0 * k0
    elif math.isfinite(kts) and not math.isfinite(k0):
        inv = 1.0 / k_eff - 1.0 / kts
        k0 = 1.0 / inv if inv > 0 else 100.0 * kts
    elif not math.isfinite(k0):
        k_stick = scale.k_stick_N_per_m
        if not math.isnan(k_stick) and k_stick > 0:
            # the interface is at least a little stiffer than the series, and at most STIFF_CAP
            # times it (a rigid interface: the drive spring alone is the compliance)
            kts = min(max(k_stick, 1.05 * k_eff), STIFF_CAP * k_eff)
            k0 = 1.0 / (1.0 / k_eff - 1.0 / kts)
        else:
            k0 = k_eff * (1.0 + 1.0 / PRESET_KTS_RATIO)
            kts = k0 * PRESET_KTS_RATIO
    out["k0_N_per_m"], out["kts_N_per_m"] = k0, kts
    if "kt0_N_per_m" in current:
        out["kt0_N_per_m"] = kts * PRESET_KT0_N_PER_M / PRESET["kts_N_per_m"]
    ring = scale.ringing
    if ring.resolved:
        # in stick the mass rings between drive spring and interface (ringing.py)
        m = fixed.get("m_kg", ringing_mass(ring, k0, kts))
        c0 = 2.0 * max(ring.decay_per_s, 0.0) * m
    else:
        # a global slip is the mass on the drive spring (all elements slide): keep the preset's
        # slip frequency sqrt(K0/M) and damping ratio C0 / (2 sqrt(K0 M))
        omega2 = PRESET["k0_N_per_m"] / PRESET["m_kg"]
        zeta = PRESET["c0_N_s_per_m"] / (2.0 * math.sqrt(PRESET["k0_N_per_m"] * PRESET["m_kg"]))
        m = fixed.get("m_kg", k0 / omega2)
        c0 = 2.0 * zeta * math.sqrt(k0 * m)
    out["m_kg"] = m
    out["c0_N_s_per_m"] = fixed.get("c0_N_s_per_m", c0)
    out.update({k: v for k, v in fixed.items() if k in current})
    return {k: float(v) for k, v in out.items() if k in current and math.isfinite(v)}


def scale_ratios(scale: DataScale, base: Mapping[str, float],
                 sample_rate_hz: float) -> dict[str, float]:
    """Data / preset ratio of each quantity a parameter may scale with (``ParamSpec.scales_with``,
    :data:`rigctl.model.params.SCALES`)."""
    k0 = base.get("k0_N_per_m", PRESET["k0_N_per_m"])
    m = base.get("m_kg", PRESET["m_kg"])
    keff_preset = 1.0 / (1.0 / PRESET["k0_N_per_m"] + 1.0 / PRESET["kts_N_per_m"])
    drop_preset = 2.0 * (PRESET["mu_s"] - PRESET["mu_k"]) * PRESET_FN_N
    drop = 2.0 * (scale.mu_peak - scale.mu_trough) * scale.fn_N \
        if math.isfinite(scale.mu_trough) and scale.mu_trough < scale.mu_peak else math.nan
    slip_preset = drop_preset / keff_preset
    return {
        "fn": scale.fn_N / PRESET_FN_N,
        "drive_velocity": scale.v_m_per_s / PRESET_V_M_PER_S,
        "slip_velocity": (drop / math.sqrt(k0 * m))
        / (drop_preset / math.sqrt(PRESET["k0_N_per_m"] * PRESET["m_kg"])),
        "slip_length": (drop / scale.k_eff_N_per_m) / slip_preset,
        "stick_time": scale.stick_s / (slip_preset / PRESET_V_M_PER_S),
        "sample_time": PRESET_SAMPLE_RATE_HZ / sample_rate_hz,
        "damping": math.sqrt(k0 * m / (PRESET["k0_N_per_m"] * PRESET["m_kg"])),
    }


def scale_effect_values(
    table: Iterable[tuple[str, float, float, float, str]], ratios: Mapping[str, float],
) -> dict[str, float]:
    """Effect parameters carried to the data's scale.

    ``table`` rows are (name, value, lower, upper, scales_with) of the effect's parameters; a
    parameter whose quantity has a ratio outside [1/NEAR_PRESET, NEAR_PRESET] is multiplied by it
    (clipped to its bounds); others keep their value. Returns only the changed ones.
    """
    out: dict[str, float] = {}
    for name, value, lower, upper, kind in table:
        r = ratios.get(kind, math.nan)
        if not (math.isfinite(r) and r > 0) or 1.0 / NEAR_PRESET <= r <= NEAR_PRESET:
            continue
        if value == 0.0:
            continue
        out[name] = float(min(max(value * r, lower), upper))
    return out
