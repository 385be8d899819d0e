"""Synthetic stick-slip records built by hand (no engine): known drops, ringing, noise."""

from __future__ import annotations

import numpy as np

from rigctl.data import MeasuredRun


def sawtooth_run(
    *,
    duration_s: float = 30.0,
    fs_hz: float = 1024.0,
    peak_N: float = 45.0,
    trough_N: float = 25.0,
    rate_N_per_s: float = 5.0,
    k_N_per_m: float = 1.0e6,
    ring_N: float = 4.0,
    ring_tau_s: float = 0.02,
    noise_N: float = 0.05,
    fn_N: float = 300.0,
    velocity_m_s: float = 1e-5,
    t_load_start_s: float = 0.0,
    sign: float = 1.0,
    seed: int = 0,
    source: str = "synthetic.csv",
) -> tuple[MeasuredRun, np.ndarray]:
    """A run whose Ft ramps from 0 (initial loading) and then saws between trough and peak.

    Returns the run and the true slip times. Each slip is instantaneous and followed by an aliased
    ring (130 Hz apparent, decaying with ring_tau_s) about the settled level.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    ft = np.zeros_like(t)
    slips = []
    level = 0.0
    t_last = t_load_start_s
    base = 0.0
    cum_slip = 0.0
    delta = np.zeros_like(t)
    slip_m = (peak_N - trough_N) / k_N_per_m * 1.5
    ring = np.zeros_like(t)
    for i, ti in enumerate(t):
        if ti < t_load_start_s:
            ft[i] = 0.0
            delta[i] = 0.0
            continue
        level = base + rate_N_per_s * (ti - t_last)
        if level >= peak_N:
            slips.append(ti)
            base = trough_N
            t_last = ti
            level = trough_N
            cum_slip += slip_m
        ft[i] = level
        delta[i] = cum_slip + level / k_N_per_m
    for ts in slips:
        sel = t >= ts
        dt = t[sel] - ts
        ring[sel] += ring_N * np.exp(-dt / ring_tau_s) * np.cos(2 * np.pi * 130.0 * dt)
    ft = sign * (ft + ring) + rng.normal(0.0, noise_N, t.size)
    x = velocity_m_s * np.clip(t - t_load_start_s, 0.0, None)
    run = MeasuredRun(
        t_s=t, x_stage_m=x, fn_N=fn_N + rng.normal(0.0, 0.2, t.size), ft_N=ft,
        d1_m=sign * delta + rng.normal(0.0, 1e-8, t.size), d2_m=np.zeros_like(t), source=source,
    )
    return run, np.array(slips)
