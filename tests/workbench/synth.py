"""Synthetic stick-slip records: built by hand (known drops, ringing, noise), or simulated for a
rig that is not this one."""

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
    ring_hz: float = 130.0,
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
    ring (ring_hz apparent, decaying with ring_tau_s) about the settled level.
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
        ring[sel] += ring_N * np.exp(-dt / ring_tau_s) * np.cos(2 * np.pi * ring_hz * dt)
    ft = sign * (ft + ring) + rng.normal(0.0, noise_N, t.size)
    x = velocity_m_s * np.clip(t - t_load_start_s, 0.0, None)
    run = MeasuredRun(
        t_s=t, x_stage_m=sign * x, fn_N=fn_N + rng.normal(0.0, 0.2, t.size), ft_N=ft,
        d1_m=sign * delta + rng.normal(0.0, 1e-8, t.size), d2_m=np.zeros_like(t), source=source,
    )
    return run, np.array(slips)


ANOTHER_RIG = {"k0_N_per_m": 2e4, "kts_N_per_m": 2e5, "m_kg": 0.01, "mu_s": 0.5, "mu_k": 0.4,
               "mu_smax": 0.55, "kt0_N_per_m": 3e5, "c0_N_s_per_m": 0.28, "n_elements": 10}
"""A rig that is not this one: soft drive, 10 N, damping ratio 1 %, 0.5 s stick cycles."""
ANOTHER_RIG_FN_N = 10.0


def another_rig_record(duration_s: float, rate_hz: float = 500.0, cycle_s: float = 0.5,
                       source: str = "long.csv") -> MeasuredRun:
    """A record of :data:`ANOTHER_RIG` simulated by the paper model at ``rate_hz``."""
    from rigctl.model import Drive, Simulator, build_model
    from rigctl.model.noise import NoiseModel

    r = ANOTHER_RIG
    keff = 1.0 / (1.0 / r["k0_N_per_m"] + 1.0 / r["kts_N_per_m"])
    v = 2.0 * (r["mu_s"] - r["mu_k"]) * ANOTHER_RIG_FN_N / keff / cycle_s
    res = Simulator(build_model("paper", params=dict(r)), sample_rate_hz=rate_hz).run(
        Drive.constant(ANOTHER_RIG_FN_N, v, duration_s),
        noise=NoiseModel(ft_rms_N=0.01, fn_rms_N=0.01), seed=1, record_elements=False)
    run = res.to_measured()
    run.source = source
    return run


LIGHT_RIG = {"k0_N_per_m": 1.9e3, "kts_N_per_m": 4.1e3, "m_kg": 0.13, "c0_N_s_per_m": 0.32,
             "mu_s": 0.39, "mu_k": 0.29, "mu_smax": 0.45, "kt0_N_per_m": 6.5e3, "n_elements": 29}
"""A light slider on a soft drive (held-out seed 3 case 6): it rings at 34 Hz after every slip,
at 1 % damping for about a second, i.e. through the whole next stick (about 1 s at 70 N and
7.4 mm/s)."""


def light_rig_tlre(c0_N_s_per_m: float) -> list[MeasuredRun]:
    """A 30 s TLRE of :data:`LIGHT_RIG` with drive damping ``c0_N_s_per_m``, at 3450 Hz and this
    rig's (low) noise."""
    from rigctl.model import build_model
    from rigctl.workbench.campaigns import simulate_campaign

    rig = {**LIGHT_RIG, "c0_N_s_per_m": c0_N_s_per_m}
    return simulate_campaign(build_model("paper", params=rig), "tlre", seed=3,
                             sample_rate_hz=3450.0, fn_N=70.0, velocity_m_s=7.4e-3,
                             duration_scale=0.5)
