"""Mechanical figures of a run in the style of the paper's Figs. 3b, 5 and 6 (matplotlib, Agg).

Each function writes one PNG and returns its file name (relative to the report folder). Figures are
built on :class:`matplotlib.figure.Figure` objects, never through pyplot's global state.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from rigctl.analysis.stickslip import STAGE_INITIAL, PassRecord
from rigctl.analysis.stiffness import CycleStiffness

DPI = 110
MAX_POINTS = 20000
PASS_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2")


def colour(i: int) -> str:
    return PASS_COLOURS[i % len(PASS_COLOURS)]


FLAT_SPAN = 1e-3
"""A linear y axis whose range is narrower than this fraction of its level is widened to
+-FLAT_HALF_WIDTH of the level: matplotlib would zoom onto values equal to four digits (with an
offset such as "1e-5+1.413") and make them look like a trend."""
FLAT_HALF_WIDTH = 0.025


def _widen_flat_axes(fig: Figure) -> None:
    for ax in fig.axes:
        if ax.get_yscale() != "linear" or ax.images:  # an image's rows are never "flat"
            continue
        lo, hi = sorted(ax.get_ylim())  # an inverted axis (images, depth) has lo > hi
        mid = 0.5 * (lo + hi)
        if mid != 0.0 and np.isfinite(mid) and hi - lo < FLAT_SPAN * abs(mid):
            ax.set_ylim(mid - FLAT_HALF_WIDTH * abs(mid), mid + FLAT_HALF_WIDTH * abs(mid))


def save(fig: Figure, folder: Path, name: str) -> str:
    _widen_flat_axes(fig)
    fig.tight_layout()
    fig.savefig(folder / name, dpi=DPI)
    return name


def _decimate(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_POINTS))


def ft_time(recs: Sequence[PassRecord], folder: Path, name: str = "ft_time.png") -> str:
    """Ft against time since the motion start, every pass (Figs. 3b and 5): stages and cycles."""
    fig = Figure(figsize=(9, 3.8))
    ax = fig.subplots()
    for i, rec in enumerate(recs):
        t = rec.run.t_s - rec.pas.t_motion_s
        s = _decimate(t.shape[0])
        ax.plot(t[s], rec.run.ft_N[s], lw=0.8, color=colour(i),
                label=f"pass {rec.pas.index + 1} (Fn {rec.pas.fn_N:.0f} N)")
        c = rec.cycles
        ax.plot(c.t_peak_s - rec.pas.t_motion_s, c.peak_N, "^", ms=4, color=colour(i))
        ax.plot(c.t_peak_s - rec.pas.t_motion_s, c.trough_N, "v", ms=4, color=colour(i))
        if i == 0 and rec.has_initial and c.n:
            ax.axvspan(0.0, c.t_end_s[0] - rec.pas.t_motion_s, color="#f4e3c1", alpha=0.6,
                       lw=0, label="initial stage (pass 1)")
    ax.set_xlabel("time since the stage started [s]")
    ax.set_ylabel("Ft [N]")
    ax.set_title("Tangential force: peaks (^) and settled troughs (v) of each cycle")
    ax.legend(fontsize=8, loc="lower right")
    return save(fig, folder, name)


def ft_delta(rec: PassRecord, stiff: Sequence[CycleStiffness], folder: Path, name: str) -> str:
    """Fig. 6a-c: (a) Ft-delta of the pass, (b) its initial stage, (c) a stable cycle, (d) K_I."""
    fig = Figure(figsize=(11, 7.5))
    axs = fig.subplots(2, 2)
    run = rec.run
    ok = rec.delta_valid
    t = run.t_s
    i_m = int(np.searchsorted(t, rec.pas.t_motion_s))
    d = np.where(ok, run.delta_m, np.nan)
    # delta's zero: the last valid samples up to motion (a re-centring may hide the very last)
    before = d[: i_m + 1][ok[: i_m + 1]]
    d0 = float(np.median(before[-64:])) if before.size else 0.0
    d_um = (d - d0) * 1e6
    s = _decimate(t.shape[0] - i_m)
    ax = axs[0, 0]
    ax.plot(d_um[i_m:][s], run.ft_N[i_m:][s], lw=0.6, color="#333")
    ax.set_xlabel("delta [um]")
    ax.set_ylabel("Ft [N]")
    ax.set_title("(a) Ft against relative displacement")
    if 1 - ok.mean() >= 0.005:  # not the short windows of the probes' re-centrings
        ax.text(0.02, 0.95, f"probe over range for {100 * (1 - ok.mean()):.0f} % of the pass "
                "(not drawn)", transform=ax.transAxes, fontsize=8, va="top", color="#b00")

    def stick(ax_c: Axes, j: int, title: str) -> None:
        c = rec.cycles
        a = int(np.searchsorted(t, c.t_start_s[j]))
        b = int(np.searchsorted(t, c.t_peak_s[j]))
        ax_c.set_title(title)
        ax_c.set_xlabel("delta [um]")
        ax_c.set_ylabel("Ft [N]")
        if not ok[a:b].any():
            ax_c.text(0.5, 0.5, "delta not measured here\n(probe over range)", ha="center",
                      va="center", transform=ax_c.transAxes, color="#b00")
            return
        ax_c.plot(d_um[a:b], run.ft_N[a:b], lw=0.7, color="#1f77b4")
        kin = stiff[j].k_inst
        f = np.array([b_.ft_mid_N for b_ in kin])
        k = np.array([b_.k_N_per_m for b_ in kin]) / 1e6
        se = np.array([b_.se_N_per_m for b_ in kin]) / 1e6
        ax_k.errorbar(f, k, yerr=se, fmt="o-", ms=4, capsize=2,
                      label=f"cycle {j + 1} ({c.stage[j]})")

    st = np.flatnonzero(rec.stable)
    ax_k = axs[1, 1]
    if rec.has_initial and rec.cycles.n:
        stick(axs[0, 1], 0, "(b) initial stage")
    else:
        axs[0, 1].text(0.5, 0.5, "no initial stage in this pass", ha="center",
                       transform=axs[0, 1].transAxes)
    if st.size:
        j = int(st[min(1, st.size - 1)])
        stick(axs[1, 0], j, f"(c) stable stage, cycle {j + 1}")
    else:
        axs[1, 0].text(0.5, 0.5, "no stable cycle", ha="center", transform=axs[1, 0].transAxes)
    ax_k.set_xlabel("Ft [N]")
    ax_k.set_ylabel("K_I = dFt/d(delta) [MN/m]")
    ax_k.set_title("(d) instantaneous stiffness along the curves (b) and (c)")
    if ax_k.get_legend_handles_labels()[0]:
        ax_k.legend(fontsize=8)
    ax_k.set_ylim(bottom=0)
    return save(fig, folder, name)


def k_cycles(recs: Sequence[PassRecord], stiff: Sequence[Sequence[CycleStiffness]],
             folder: Path, name: str = "k_cycles.png", label: str = "pass") -> str:
    """Fig. 6d / 10d: K(i) against the cycle number, one line per pass."""
    fig = Figure(figsize=(6.5, 4))
    ax = fig.subplots()
    for i, (rec, st) in enumerate(zip(recs, stiff, strict=True)):
        k = np.array([c.k.k_N_per_m for c in st]) / 1e6
        se = np.array([c.k.se_N_per_m for c in st]) / 1e6
        cyc = np.arange(1, k.shape[0] + 1)
        lab = f"Fn {rec.pas.fn_N:.0f} N" if label == "fn" else f"pass {rec.pas.index + 1}"
        ax.errorbar(cyc, k, yerr=se, fmt="o-", ms=4, color=colour(i), label=lab, capsize=2)
        init = [c.stage == STAGE_INITIAL for c in st]
        if any(init):
            ax.plot(cyc[np.array(init)], k[np.array(init)], "s", ms=9, mfc="none",
                    color=colour(i))
    ax.set_xlabel("cycle i")
    ax.set_ylabel("K(i) [MN/m]")
    ax.set_title("K(i): slope of the initial linear part of each cycle (square: initial stage)")
    ax.legend(fontsize=8)
    return save(fig, folder, name)
