"""Figures of the workbench (matplotlib, Agg backend): overlays, loops, features, residual map,
periodic patterns of the residual, ranking and the error-fall chart. Each function writes one PNG
and returns its path."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rigctl.data import MeasuredRun
from rigctl.model import SimResult
from rigctl.records.dataset import Dataset
from rigctl.records.feature_info import FEATURES
from rigctl.records.features import COVARIATES, EVENT_FEATURES, EventTable
from rigctl.workbench.periodic import sinusoid
from rigctl.workbench.ranking import CandidateScore
from rigctl.workbench.residual_map import (
    COVARIATE_NAMES,
    Pattern,
    ResidualMap,
    pattern_text,
    trend_matrix,
)

MEAS = "#444444"
MODEL = "#d62728"
DPI = 110


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def overlay_time(
    runs: Sequence[MeasuredRun], results: Sequence[SimResult], dataset: Dataset,
    model_events: Sequence[EventTable], path: Path, max_runs: int = 4,
) -> Path:
    """Ft against time per run (left) and one cycle-aligned slip (right)."""
    n = min(len(runs), max_runs)
    fig, axes = plt.subplots(n, 2, figsize=(12, 2.8 * n), squeeze=False,
                             gridspec_kw={"width_ratios": [3, 1]})
    for k in range(n):
        run, res, prep, mev = runs[k], results[k], dataset.runs[k], model_events[k]
        t = run.t_s - run.t_s[0]
        ax = axes[k][0]
        ax.plot(t, run.ft_N, color=MEAS, lw=0.7, label="measured")
        ax.plot(res.t_s, res.ft_N, color=MODEL, lw=0.7, alpha=0.8, label="model")
        ax.set_ylabel("Ft [N]")
        ax.set_title(prep.name, fontsize=9, loc="left")
        if k == n - 1:
            ax.set_xlabel("time [s]")
        if k == 0:
            ax.legend(loc="lower right", fontsize=8)
        ax2 = axes[k][1]
        ev = prep.events
        if ev.n and mev.n:
            j = ev.n // 2
            tm = ev.t_drop_s[j]
            jm = int(np.argmin(np.abs(mev.t_drop_s - tm)))
            ts = mev.t_drop_s[jm]
            win = (-0.15, 0.25)
            sel = (t >= tm + win[0]) & (t <= tm + win[1])
            sel_m = (res.t_s >= ts + win[0]) & (res.t_s <= ts + win[1])
            ax2.plot((t[sel] - tm) * 1e3, run.ft_N[sel], color=MEAS, lw=0.9, marker=".", ms=2)
            ax2.plot((res.t_s[sel_m] - ts) * 1e3, res.ft_N[sel_m], color=MODEL, lw=0.9,
                     marker=".", ms=2)
            ax2.set_title(f"slip {j + 1}, aligned at the drop", fontsize=9, loc="left")
        if k == n - 1:
            ax2.set_xlabel("time from drop [ms]")
    return _save(fig, path)


def loops(runs: Sequence[MeasuredRun], results: Sequence[SimResult], dataset: Dataset,
          model_events: Sequence[EventTable], path: Path) -> Path:
    """Ft against delta for the first run: the initial stage and first cycles (left), and two
    stable cycles around the middle slip, delta taken from that slip (right)."""
    run, res, prep, mev = runs[0], results[0], dataset.runs[0], model_events[0]
    t = run.t_s - run.t_s[0]
    d = run.delta_m - run.delta_m[0]
    dm = (res.d1_m - res.d2_m) - (res.d1_m[0] - res.d2_m[0])
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    ev = prep.events
    t_end = ev.t_drop_s[min(3, ev.n - 1)] + 0.5 if ev.n else t[-1]
    sel, sel_m = t <= t_end, res.t_s <= t_end
    axes[0].plot(d[sel] * 1e6, run.ft_N[sel], color=MEAS, lw=0.7, label="measured")
    axes[0].plot(dm[sel_m] * 1e6, res.ft_N[sel_m], color=MODEL, lw=0.7, label="model")
    axes[0].set_title(f"{prep.name}: initial stage and first cycles", fontsize=9, loc="left")
    axes[0].legend(fontsize=8, loc="lower right")
    if ev.n >= 3 and mev.n >= 3:
        j = ev.n // 2
        tm = ev.t_drop_s[j]
        jm = int(np.argmin(np.abs(mev.t_drop_s - tm)))
        ts = mev.t_drop_s[jm]
        span = (ev.t_drop_s[j] - ev.t_drop_s[j - 1]) * 1.05
        s1 = (t >= tm - span) & (t <= tm + span)
        s2 = (res.t_s >= ts - span) & (res.t_s <= ts + span)
        d0 = float(np.interp(tm, t, d))
        d0m = float(np.interp(ts, res.t_s, dm))
        axes[1].plot((d[s1] - d0) * 1e6, run.ft_N[s1], color=MEAS, lw=0.7)
        axes[1].plot((dm[s2] - d0m) * 1e6, res.ft_N[s2], color=MODEL, lw=0.7)
        axes[1].set_title(f"stable cycles around slip {j + 1} (delta from the slip)", fontsize=9,
                          loc="left")
    for ax in axes:
        ax.set_xlabel("delta [um]")
        ax.set_ylabel("Ft [N]")
    return _save(fig, path)


def features(dataset: Dataset, model_events: Sequence[EventTable], path: Path) -> Path:
    """Per-event features against time: measured (dots) and model (crosses)."""
    names = ("peak_N", "trough_N", "stick_s", "k_stick_N_per_m", "ring_N", "slip_m")
    fig, axes = plt.subplots(2, 3, figsize=(12, 6))
    offset = 0.0
    for run, mev in zip(dataset.runs, model_events, strict=True):
        for ax, name in zip(axes.flat, names, strict=True):
            ax.plot(run.events.t_drop_s + offset, run.events.features[name], ".", color=MEAS,
                    ms=4)
            ax.plot(mev.t_drop_s + offset, mev.features[name], "x", color=MODEL, ms=4)
        offset += run.n_samples / run.sample_rate_hz
    for ax, name in zip(axes.flat, names, strict=True):
        info = FEATURES[name]
        ax.set_title(f"{info.phrase} [{info.unit}]", fontsize=9, loc="left")
        ax.set_xlabel("campaign time [s] (runs end to end)")
    axes.flat[0].legend(["measured", "model"], fontsize=8)
    return _save(fig, path)


def residual_heatmap(rmap: ResidualMap, path: Path) -> Path:
    """Trend amplitude (z) of every feature against every covariate; stage and phase bars."""
    amp = trend_matrix(rmap)
    fig = plt.figure(figsize=(12, 5.5))
    ax = fig.add_axes((0.24, 0.28, 0.44, 0.65))
    vmax = max(1.0, float(np.max(np.abs(amp))))
    im = ax.imshow(amp, cmap="RdBu_r", vmin=-vmax, vmax=vmax, aspect="auto")
    ax.set_xticks(range(len(COVARIATES)))
    ax.set_xticklabels([COVARIATE_NAMES[c] for c in COVARIATES], rotation=40, ha="right",
                       fontsize=8)
    ax.set_yticks(range(len(EVENT_FEATURES)))
    ax.set_yticklabels([FEATURES[f].phrase[:40] for f in EVENT_FEATURES], fontsize=8)
    ax.set_title("residual trend vs covariate (z; |t| >= 3 shown)", fontsize=9, loc="left")
    fig.colorbar(im, ax=ax, fraction=0.04)
    ax2 = fig.add_axes((0.76, 0.58, 0.22, 0.35))
    st = rmap.by_stage
    labels = [f for f in EVENT_FEATURES if np.isfinite(st["initial"].get(f, np.nan))
              or np.isfinite(st["stable"].get(f, np.nan))]
    y = np.arange(len(labels))
    ax2.barh(y - 0.2, [st["initial"].get(f, np.nan) for f in labels], 0.4, label="initial")
    ax2.barh(y + 0.2, [st["stable"].get(f, np.nan) for f in labels], 0.4, label="stable")
    ax2.set_yticks(y)
    # the feature's name without its unit (drop_N and drop_delay_s are both "drop" by their
    # first word)
    ax2.set_yticklabels([re.sub(r"_(N|s|m|N_per_s|N_per_m)$", "", f) for f in labels], fontsize=7)
    ax2.set_title("mean z by stage", fontsize=9, loc="left")
    ax2.legend(fontsize=7)
    ax3 = fig.add_axes((0.76, 0.12, 0.22, 0.3))
    ax3.bar(list(rmap.by_phase), list(rmap.by_phase.values()), color=["#1f77b4", "#ff7f0e"])
    ax3.set_title("RMS z by phase", fontsize=9, loc="left")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


_AXIS_SCALE: dict[str, tuple[float, str]] = {"x_drive_m": (1e6, "um"), "t_s": (1.0, "s")}
"""Each pattern covariate's axis: factor from SI and unit."""
_RESIDUAL_SCALE: dict[str, tuple[float, str]] = {"m": (1e6, "um"), "s": (1e3, "ms")}
"""A residual in metres or seconds is drawn in um or ms (ratio features in %, the rest in SI)."""


def periodic_patterns(patterns: Sequence[Pattern], path: Path, max_panels: int = 4) -> Path:
    """Each pattern's residual against its covariate, each run less its straight line (dots, one
    colour per run), with the run's fitted sinusoid (line); the sentence of the map as title."""
    shown = list(patterns[:max_panels])
    fig, axes = plt.subplots(len(shown), 1, figsize=(10, 3.2 * len(shown)), squeeze=False)
    for ax, p in zip(axes[:, 0], shown, strict=True):
        info = FEATURES[p.feature]
        xs, x_unit = _AXIS_SCALE[p.covariate]
        ys, y_unit = (100.0, "%") if info.log else _RESIDUAL_SCALE.get(info.unit, (1.0, info.unit))
        for k, run in enumerate(p.fit.runs):
            colour = f"C{k % 10}"
            ax.plot(run.x * xs, run.y * ys, ".", color=colour, ms=4, alpha=0.7)
            grid = np.linspace(float(run.x.min()), float(run.x.max()), 400)
            ax.plot(grid * xs, sinusoid(p.fit, run, grid) * ys, "-", color=colour, lw=1.2)
        where = "track position in the run (drive position at the slip)" \
            if p.covariate == "x_drive_m" else COVARIATE_NAMES[p.covariate]
        ax.set_xlabel(f"{where} [{x_unit}]")
        ax.set_ylabel(f"residual, less each run's line [{y_unit}]", fontsize=8)
        ax.axhline(0.0, color="#bbbbbb", lw=0.8)
        title = pattern_text(p)
        if len(title) > 110:
            cut = title.rfind(" ", 0, 110)
            title = title[:cut] + "\n" + title[cut + 1:]
        ax.set_title(title, fontsize=9, loc="left")
    return _save(fig, path)


def ranking(scores: Sequence[CandidateScore], baseline_error: float, path: Path) -> Path:
    """Error of base + each candidate (significant ones coloured) against the baseline."""
    scores = [s for s in scores if np.isfinite(s.error)]
    fig, ax = plt.subplots(figsize=(8, 0.35 * max(len(scores), 3) + 1.2))
    y = np.arange(len(scores))[::-1]
    # a set --auto only screened (its error a linear re-fit, not a fit) is drawn hatched
    screened = [s.explains.startswith("screened only") for s in scores]
    colors = ["#2ca02c" if s.significant else "#bbbbbb" for s in scores]
    bars = ax.barh(y, [s.error for s in scores], color=colors)
    for bar, only in zip(bars, screened, strict=True):
        if only:
            bar.set_facecolor("white")
            bar.set_edgecolor("#999999")
            bar.set_hatch("///")
    ax.axvline(baseline_error, color="k", ls="--", lw=1, label=f"baseline {baseline_error:.3g}")
    ax.set_yticks(y)
    ax.set_yticklabels([f"{s.effect} (screened)" if only else
                        f"{s.effect} (dBIC {s.delta_bic:.0f})"
                        for s, only in zip(scores, screened, strict=True)], fontsize=8)
    ax.set_xlabel("error E (event-aware, in units of measured scatter)")
    ax.set_xscale("log")
    ax.legend(fontsize=8)
    ax.set_title("base + candidate effect (green: significant"
                 + ("; hatched: screened only)" if any(screened) else ")"),
                 fontsize=9, loc="left")
    return _save(fig, path)


def error_fall(labels: Sequence[str], errors: Sequence[float], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 3.5))
    x = np.arange(len(errors))
    ax.plot(x, errors, "o-", color=MODEL)
    for xi, e in zip(x, errors, strict=True):
        ax.annotate(f"{e:.3g}", (xi, e), textcoords="offset points", xytext=(0, 6),
                    ha="center", fontsize=8)
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("error E")
    ax.set_yscale("log")
    ax.axhline(1.0, color="#888888", ls=":", lw=1)
    ax.set_title("error at each step (dotted: measurement scatter)", fontsize=9, loc="left")
    return _save(fig, path)


def image_ratios(rows: Sequence[dict[str, object]], path: Path) -> Path:
    """The contact images against the model's stress distribution, one panel per run with frames:
    the per-part load ratio r(k) of the initial to the stable stage read from the images at equal
    light (dots) and the model's (line), with both tilts (:mod:`rigctl.records.image_features`)."""
    n = max(len(rows), 1)
    fig, axes = plt.subplots(1, n, figsize=(5.0 * n, 3.6), squeeze=False)
    for ax, row in zip(axes[0], rows, strict=False):
        r_meas = np.asarray(row["r_measured"], dtype=np.float64)
        k = np.arange(1, r_meas.size + 1)
        ax.axhline(1.0, color="#bbbbbb", lw=0.8)
        ax.plot(k, r_meas, "o", color=MEAS, ms=5,
                label=f"images: tilt {float(row['p_tilt_initial']):.3f} "  # type: ignore[arg-type]
                      f"+- {float(row['p_tilt_initial_sigma']):.3f}")  # type: ignore[arg-type]
        r_model = row.get("r_model")
        model = row.get("model")
        if r_model is not None and isinstance(model, dict):
            ax.plot(k, np.asarray(r_model, dtype=np.float64), "-", color=MODEL, lw=1.2,
                    label=f"model: tilt {float(model.get('p_tilt_initial', np.nan)):.3f}")
        ax.set_xticks(k)
        ax.set_xlabel("part k along x (1 = back end)")
        ax.set_ylabel("r(k): initial / stable load share")
        ax.set_title(Path(str(row["name"])).name, fontsize=9, loc="left")
        ax.legend(fontsize=8, loc="upper left")
    return _save(fig, path)
