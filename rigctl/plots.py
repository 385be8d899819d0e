"""Plots of runs people look at rather than read: Ft(t) and the Ft-delta loop (paper Figs. 5-6)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from rigctl.model.result import SimResult


def plot_run(res: SimResult, path: Path, title: str = "") -> None:
    """Two panels: tangential force against time (initial/stable stage coloured, slips marked) and
    tangential force against the relative interface displacement delta."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    ini = res.stage == 0
    ax1.plot(res.t_s[ini], res.ft_N[ini], lw=0.8, color="tab:blue", label="initial stage")
    ax1.plot(res.t_s[~ini], res.ft_N[~ini], lw=0.8, color="tab:orange", label="stable stage")
    if res.events:
        ax1.plot([e.t_start_s for e in res.events], [e.peak_N for e in res.events], "v",
                 ms=4, color="k", label="slip (peak)")
    ax1.set_xlabel("time t [s]")
    ax1.set_ylabel("tangential force Ft [N]")
    ax1.legend(loc="lower right", fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.plot(res.delta_m[ini] * 1e6, res.ft_N[ini], lw=0.8, color="tab:blue")
    ax2.plot(res.delta_m[~ini] * 1e6, res.ft_N[~ini], lw=0.5, color="tab:orange")
    ax2.set_xlabel("relative displacement delta [um]")
    ax2.set_ylabel("tangential force Ft [N]")
    ax2.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
