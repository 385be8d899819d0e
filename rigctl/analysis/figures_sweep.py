"""Force-sweep figures in the style of the paper's Figs. 10 and 11 (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rigctl.analysis.figures_mech import colour, save
from rigctl.analysis.sweep import SweepSummary


def sweep_figures(sw: SweepSummary, folder: Path) -> list[str]:
    """Fig. 10 (b) mu's vs Fn, (c) K(1) vs Fn, (d) K(i) vs cycle per Fn; Fig. 11 (c, d) with Im(1)."""
    pts = sw.points
    fn = np.array([p.fn_N for p in pts])
    fig = Figure(figsize=(12, 3.8))
    ax_mu, ax_k1, ax_ki = fig.subplots(1, 3)
    mu_max = np.array([p.friction.mu_s_max for p in pts])
    mu_s = np.array([p.friction.mu_s.mean for p in pts])
    mu_s_sd = np.array([p.friction.mu_s.std for p in pts])
    mu_k = np.array([p.friction.mu_k.mean for p in pts])
    mu_k_sd = np.array([p.friction.mu_k.std for p in pts])
    ax_mu.plot(fn, mu_max, "s-", label="mu_s,max")
    ax_mu.errorbar(fn, mu_s, yerr=mu_s_sd, fmt="o-", capsize=2, label="mu_s")
    ax_mu.errorbar(fn, mu_k, yerr=mu_k_sd, fmt="v-", capsize=2, label="mu_k")
    ax_mu.set_xlabel("Fn [N]")
    ax_mu.set_ylabel("friction coefficient")
    ax_mu.set_title("(b) friction coefficients")
    ax_mu.legend(fontsize=8)
    k1 = np.array([p.k1_N_per_m for p in pts]) / 1e6
    ax_k1.plot(fn, k1, "o-")
    ax_k1.set_xlabel("Fn [N]")
    ax_k1.set_ylabel("K(1) [MN/m]")
    ax_k1.set_title("(c) K(1) against Fn")
    for i, p in enumerate(pts):
        k = np.array(p.k_N_per_m) / 1e6
        ax_ki.plot(np.arange(1, k.size + 1), k, "o-", ms=3, color=colour(i),
                   label=f"{p.fn_N:.0f} N")
    ax_ki.set_xlabel("cycle i")
    ax_ki.set_ylabel("K(i) [MN/m]")
    ax_ki.set_title("(d) K(i) per normal force")
    ax_ki.legend(fontsize=7, ncol=2)
    names = [save(fig, folder, "sweep_fig10.png")]

    drop = np.array([p.relative_drop for p in pts])
    fig = Figure(figsize=(12, 3.8))
    ax_d, ax_im, ax_imk = fig.subplots(1, 3)
    ax_d.plot(fn, drop, "o-")
    ax_d.set_xlabel("Fn [N]")
    ax_d.set_ylabel("stable drop / peak")
    ax_d.set_title("stick-slip strength (where it fades)")
    im1 = np.array([p.im1 for p in pts])
    has = np.isfinite(im1)
    if has.any():
        ax_im.plot(fn[has], im1[has], "o-")
        ax_imk.plot(im1[has], k1[has], "o")
        for f, x, y in zip(fn[has], im1[has], k1[has], strict=True):
            ax_imk.annotate(f"{f:.0f} N", (x, y), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
    else:
        for ax in (ax_im, ax_imk):
            ax.text(0.5, 0.5, "no camera frames:\nIm(1) not measured", ha="center",
                    va="center", transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
    ax_im.set_xlabel("Fn [N]")
    ax_im.set_ylabel("Im(1) [grey level]")
    ax_im.set_title("Fig. 11c: Im(1) against Fn")
    ax_imk.set_xlabel("Im(1) [grey level]")
    ax_imk.set_ylabel("K(1) [MN/m]")
    ax_imk.set_title("Fig. 11d: K(1) against Im(1)")
    names.append(save(fig, folder, "sweep_fig11.png"))
    return names
