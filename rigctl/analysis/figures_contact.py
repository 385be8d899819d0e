"""Contact-image figures in the style of the paper's Figs. 3a, 4d, 7, 8-9 and 13 (matplotlib, Agg).

Each function writes one PNG into ``folder`` and returns its file name, as
:mod:`rigctl.analysis.figures_mech` does (Figure objects, never pyplot's global state).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from rigctl.analysis.contact_csi import CATEGORIES, COLOURS, csi_image
from rigctl.analysis.contact_run import ContactAnalysis, PassContact
from rigctl.analysis.contact_stress import PSnapshot
from rigctl.analysis.figures_mech import colour, save
from rigctl.analysis.stickslip import PassRecord
from rigctl.analysis.surface_psd import SurfacePsd
from rigctl.records.contact_profile import MODEL_BINS, p_density

MAX_ROWS = 1500
ISUM_LINEAR_BELOW_N = 300.0
"""Sec. 2.2: Isum is approximately linear in Fn below 300 N (Fig. 3a)."""
UNLOADED_FT_FRACTION = 0.02
MIN_FN_SPAN_N = 30.0
"""The line is fitted only when the frames' Fn spans at least this much (a loading, not a hold)."""

CATEGORY_COLOURS = {"contact separation": "#1f6fff", "new contact": "#e60000",
                    "area growth": "#f0c800", "black-region growth": "#000000"}


def _rgb(c: tuple[int, int, int]) -> tuple[float, float, float]:
    return (c[0] / 255, c[1] / 255, c[2] / 255)


def isum_fit(fn_N: np.ndarray, isum: np.ndarray, ft_N: np.ndarray | None = None,
             below_N: float = ISUM_LINEAR_BELOW_N) -> tuple[float, float, float, int]:
    """Least-squares line Isum = a Fn + b over frames with 0 < Fn <= ``below_N``: (a, b, R^2, n).

    Sec. 2.2 states the line for normal loading (the NLRE): with ``ft_N`` given, only frames
    without tangential load (``|Ft| <= UNLOADED_FT_FRACTION Fn + 0.5 N``) count. NaN when the
    frames' Fn spans less than ``MIN_FN_SPAN_N`` (no loading in the run).
    """
    sel = (fn_N > 0.0) & (fn_N <= below_N) & np.isfinite(isum)
    if ft_N is not None:
        sel &= np.abs(ft_N) <= UNLOADED_FT_FRACTION * fn_N + 0.5
    n = int(np.count_nonzero(sel))
    if n < 3 or float(np.ptp(fn_N[sel])) < MIN_FN_SPAN_N:
        return math.nan, math.nan, math.nan, n
    a, b = np.polyfit(fn_N[sel], isum[sel], 1)
    resid = isum[sel] - (a * fn_N[sel] + b)
    var = float(np.var(isum[sel]))
    r2 = 1.0 - float(np.var(resid)) / var if var > 0 else math.nan
    return float(a), float(b), r2, n


def isum_figure(ca: ContactAnalysis, folder: Path, name: str = "isum.png") -> str:
    """Fig. 3a: Isum(t) (Eq. 1) with Fn, and Isum against Fn with its line below 300 N."""
    ci = ca.intensity
    fig = Figure(figsize=(11, 3.8))
    ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.6, 1]})
    ax.plot(ci.t_s, ci.isum / 1e6, lw=0.8, color="#1f77b4")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("Isum [10^6 grey levels]", color="#1f77b4")
    ax.set_title("(a) Isum(t) (Eq. 1) and the normal force")
    axf = ax.twinx()
    axf.plot(ci.t_s, ca.fn_frames_N, lw=0.8, color="#d62728")
    axf.set_ylabel("Fn [N]", color="#d62728")
    ax2.plot(ca.fn_frames_N, ci.isum / 1e6, ".", ms=2, color="#555")
    a, b, r2, n = isum_fit(ca.fn_frames_N, ci.isum, ca.ft_frames_N)
    if math.isfinite(a):
        f = np.linspace(0.0, ISUM_LINEAR_BELOW_N, 2)
        ax2.plot(f, (a * f + b) / 1e6, color="#9467bd", lw=1.5,
                 label=f"normal loading below {ISUM_LINEAR_BELOW_N:.0f} N: R^2 = {r2:.4f} "
                       f"({n} frames)")
        ax2.legend(fontsize=8, loc="lower right")
    ax2.set_xlabel("Fn [N]")
    ax2.set_ylabel("Isum [10^6 grey levels]")
    ax2.set_title("(b) Isum against Fn")
    return save(fig, folder, name)


def _snapshots(ax: Axes, snaps: list[PSnapshot], x: np.ndarray, title: str) -> None:
    for k, s in enumerate(snaps):
        ax.plot(x, s.p_x, lw=1.2, color=colour(k), label=f"Ft = {s.ft_N:.1f} N")
    ax.set_xlabel("normalised length x (0 = back end)")
    ax.set_ylabel("P(x) (mean 1)")
    ax.set_title(title)
    ax.set_xlim(0, 1)
    if snaps:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no frames in this stage", ha="center", transform=ax.transAxes)


def fig7(ca: ContactAnalysis, pc: PassContact, rec: PassRecord, folder: Path, name: str) -> str:
    """Fig. 7: (a) P(x, t) over the pass, (b)/(c) P(x) at chosen Ft, (d) Im(i) against the cycle."""
    ci = ca.intensity
    fig = Figure(figsize=(11, 8))
    axs = fig.subplots(2, 2)
    ax = axs[0, 0]
    t0 = rec.pas.t_motion_s
    sel = np.flatnonzero((ci.t_s >= rec.run.t_s[0]) & (ci.t_s <= rec.pas.t_end_s))
    if sel.size >= 2:
        sel = sel[:: max(1, sel.size // MAX_ROWS)]
        p = p_density(ci.profile[sel])
        im = ax.imshow(p, aspect="auto", origin="lower", cmap="inferno",
                       extent=(0.0, 1.0, float(ci.t_s[sel[0]] - t0), float(ci.t_s[sel[-1]] - t0)),
                       vmin=0.0, vmax=float(np.nanpercentile(p, 99.5)) if np.isfinite(p).any()
                       else 2.0, interpolation="nearest")
        fig.colorbar(im, ax=ax, label="P(x, t)")
        c = rec.cycles
        for tp in c.t_peak_s:
            ax.axhline(tp - t0, color="w", lw=0.4, ls=":")
    else:
        ax.text(0.5, 0.5, "no frames in this pass", ha="center", transform=ax.transAxes)
    ax.set_xlabel("normalised length x (0 = back end)")
    ax.set_ylabel("time since the stage started [s]")
    ax.set_title("(a) P(x, t) (dotted: slips)")
    x = ci.x_centres
    _snapshots(axs[0, 1], pc.p_initial, x, "(b) P(x) in the initial stage")
    _snapshots(axs[1, 0], pc.p_stable, x,
               f"(c) P(x) in the stable stage (cycle {pc.stable_cycle})" if pc.stable_cycle
               else "(c) P(x) in the stable stage")
    ax = axs[1, 1]
    cyc = np.array([m.cycle for m in pc.im])
    val = np.array([m.im for m in pc.im])
    if cyc.size:
        ax.plot(cyc, val / 1e3, "o-", color="#1f77b4")
        init = np.array([m.stage == "initial" for m in pc.im])
        if init.any():
            ax.plot(cyc[init], val[init] / 1e3, "s", ms=10, mfc="none", color="#1f77b4",
                    label="initial stage")
            ax.legend(fontsize=8)
    ax.set_xlabel("cycle i")
    ax.set_ylabel("Im(i) [10^3 grey levels]")
    ax.set_title("(d) mean contact intensity over each K(i) window")
    return save(fig, folder, name)


def fig13(pc: PassContact, folder: Path, name: str) -> str:
    """Fig. 13a/c: P(k), the model's 10 parts, at chosen Ft in the initial and stable stage."""
    fig = Figure(figsize=(11, 3.8))
    axs = fig.subplots(1, 2, sharey=True)
    k = np.arange(1, MODEL_BINS + 1)
    for ax, snaps, title in ((axs[0], pc.p_initial, "(a) initial stage"),
                             (axs[1], pc.p_stable, "(b) stable stage")):
        width = 0.8 / max(len(snaps), 1)
        for j, s in enumerate(snaps):
            ax.bar(k - 0.4 + (j + 0.5) * width, s.p_k, width, color=colour(j),
                   label=f"Ft = {s.ft_N:.1f} N")
        ax.axhline(1.0 / MODEL_BINS, color="#888", lw=0.8, ls="--")
        ax.set_xticks(k)
        ax.set_xlabel("part k of the contact (1 = back end)")
        ax.set_title(title)
        if snaps:
            ax.legend(fontsize=8)
        else:
            ax.text(0.5, 0.5, "no frames in this stage", ha="center", transform=ax.transAxes)
    axs[0].set_ylabel("P(k) (sum 1)")
    return save(fig, folder, name)


def fig9(pc: PassContact, folder: Path, name: str) -> str:
    """Figs. 8-9: CSI of each stage and its pie chart of contact behaviours."""
    n = len(pc.csi)
    fig = Figure(figsize=(10, 4.2 * max(n, 1)))
    axs = fig.subplots(max(n, 1), 2, squeeze=False, gridspec_kw={"width_ratios": [1.4, 1]})
    if n == 0:
        axs[0, 0].text(0.5, 0.5, "no CSI: too few frames", ha="center")
    for row, c in enumerate(pc.csi):
        ax = axs[row, 0]
        ax.imshow(csi_image(c.code), interpolation="nearest")
        ax.set_title(f"CSI, {c.stage} stage (cycle {c.cycle}): Ft = "
                     + ", ".join(f"{f:.1f}" for f in c.ft_N) + " N", fontsize=10)
        ax.set_xlabel("x [px] (back end left)")
        ax.set_yticks([])
        handles = [Patch(facecolor=_rgb(COLOURS[k]), edgecolor="#999", label=lab)
                   for k, lab in ((1, "first"), (2, "middle"), (4, "last"), (3, "first+middle"),
                                  (5, "first+last"), (6, "middle+last"), (7, "all three"))]
        ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
        ax = axs[row, 1]
        names = list(CATEGORIES)
        vals = [c.props.proportions[k] for k in names]
        wedges, _ = ax.pie(vals, colors=[CATEGORY_COLOURS[k] for k in names],
                           wedgeprops={"edgecolor": "w"})
        ax.legend(wedges, [f"{k}: {100 * v:.1f} %" for k, v in zip(names, vals, strict=True)],
                  fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2)
        ax.set_title(f"proportions of {c.props.n_contact_px} contact pixels", fontsize=9)
    return save(fig, folder, name)


def psd_figure(psd: SurfacePsd, folder: Path, name: str = "surface_psd.png",
               height_m: np.ndarray | None = None, pixel_m: float = math.nan,
               band_per_um: tuple[float, float] = (0.02, 0.18)) -> str:
    """Fig. 4d: the isotropic PSD of a height map (log-log), the paper's stable band shaded."""
    fig = Figure(figsize=(11 if height_m is not None else 6.5, 4.2))
    axs = fig.subplots(1, 2 if height_m is not None else 1, squeeze=False)[0]
    ax = axs[-1]
    ok = np.isfinite(psd.c_m4) & (psd.c_m4 > 0)
    ax.loglog(psd.f_per_m[ok] * 1e-6, psd.c_m4[ok], "o-", ms=3, color="#1f77b4",
              label=f"Sq from the PSD {psd.sq_m * 1e6:.3f} um\n(of the heights "
                    f"{psd.sq_direct_m * 1e6:.3f} um)\nanisotropy {psd.anisotropy:.2f}")
    ax.axvspan(*band_per_um, color="#ddd", alpha=0.6, label="paper's stable band\n0.02-0.18 um^-1")
    ax.set_xlabel("spatial frequency [1/um]")
    ax.set_ylabel("C(f) [m^4]")
    ax.set_title("Isotropic power spectral density (Hann window)")
    ax.legend(fontsize=8, loc="lower left")
    if height_m is not None:
        ax0 = axs[0]
        ext = (0.0, height_m.shape[1] * pixel_m * 1e3, 0.0, height_m.shape[0] * pixel_m * 1e3)
        im = ax0.imshow(height_m * 1e6, cmap="viridis", extent=ext, origin="lower")
        fig.colorbar(im, ax=ax0, label="height [um]")
        ax0.set_xlabel("x [mm]")
        ax0.set_ylabel("y [mm]")
        ax0.set_title("height map")
    return save(fig, folder, name)
