"""The report's "Contact images" section of one run: figures, tables, the per-frame series file.

For a run with frames: Isum (Fig. 3a), per pass Fig. 7 (P(x, t), P at chosen Ft, Im(i)), Fig. 13
(P in the model's 10 parts) and Figs. 8-9 (CSI and pie charts), a table of the CSI proportions and
``<prefix>contact_frames.csv`` with one row per frame: t, Isum, Ic, Fn, Ft and P(k) for k = 1..10.
For a run without frames the section says it is absent and why.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from rigctl.analysis import figures_contact
from rigctl.analysis.contact_run import ContactAnalysis
from rigctl.analysis.mechanics import Mechanics
from rigctl.io.atomic import atomic_text_writer
from rigctl.records.contact_profile import MODEL_BINS


def _f(x: float, digits: int = 4) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}g}"


def write_series(ca: ContactAnalysis, path: Path) -> None:
    """One row per frame: t_s, Isum, Ic, Fn_N, Ft_N, P1..P10 (the model's parts)."""
    ci = ca.intensity
    pk = ca.p_k()
    with atomic_text_writer(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["t_s", "isum", "ic", "fn_N", "ft_N", *[f"P{k}" for k in
                                                          range(1, MODEL_BINS + 1)]])
        for j in range(ci.n_frames):
            w.writerow([f"{ci.t_s[j]:.6f}", f"{ci.isum[j]:.0f}", f"{ci.ic[j]:.1f}",
                        f"{ca.fn_frames_N[j]:.3f}", f"{ca.ft_frames_N[j]:.3f}",
                        *("" if not np.isfinite(v) else f"{v:.5f}" for v in pk[j])])


def contact_sections(ca: ContactAnalysis | None, absent: str, mech: Mechanics, folder: Path,
                     prefix: str) -> list[dict[str, Any]]:
    """Template sections (title, text, table, figures) of the contact analyses of one run."""
    if ca is None:
        return [{"title": "Contact images (Figs. 3a, 7, 9, 13)", "text": "Absent: " + absent,
                 "table": None, "figures": []}]
    ci = ca.intensity
    r = ci.region
    figures = [figures_contact.isum_figure(ca, folder, f"{prefix}isum.png")]
    rows: list[list[str]] = []
    for pc, rec in zip(ca.passes, mech.passes, strict=True):
        n = pc.pass_index + 1
        figures.append(figures_contact.fig7(ca, pc, rec, folder, f"{prefix}p_xt_pass{n}.png"))
        figures.append(figures_contact.fig13(pc, folder, f"{prefix}p_bins_pass{n}.png"))
        if pc.csi:
            figures.append(figures_contact.fig9(pc, folder, f"{prefix}csi_pass{n}.png"))
        for c in pc.csi:
            p = c.props.proportions
            rows.append([str(n), c.stage, str(c.cycle), ", ".join(f"{f:.1f}" for f in c.ft_N),
                         *(f"{100 * p[k]:.1f} %" if math.isfinite(p[k]) else "-" for k in p),
                         str(c.props.n_contact_px)])
    series = f"{prefix}contact_frames.csv"
    write_series(ca, folder / series)
    a, _, r2, n_fit = figures_contact.isum_fit(ca.fn_frames_N, ci.isum, ca.ft_frames_N)
    below = figures_contact.ISUM_LINEAR_BELOW_N
    if math.isfinite(a):
        fit = (f" Isum against Fn under normal load only, below {below:.0f} N: slope {_f(a)} "
               f"per N, R^2 = {_f(r2, 5)} over {n_fit} frames.")
    else:
        fit = " Fn does not vary enough without tangential load in this run for the Isum-Fn line."
    im1 = [f"pass {pc.pass_index + 1}: {_f(pc.im1)}" for pc in ca.passes]
    top = float(np.nanmax(ci.isum)) if np.isfinite(ci.isum).any() else math.nan
    text = (f"{ci.n_frames} frames; contact region image columns {r.col0}-{r.col1 - 1} "
            f"(x = 0 at the {'left' if r.back_end_left else 'right'}), dark level "
            f"{r.dark_level:.1f} grey levels; max Isum {_f(top)}.{fit} "
            f"Im(1): {', '.join(im1) or '-'}. Per-frame Isum, Ic, Fn, Ft and P(k): {series}.")
    table = {"header": ["pass", "stage", "cycle", "Ft of the 3 frames [N]",
                        "contact separation", "new contact", "area growth",
                        "black-region growth", "contact px"],
             "rows": rows} if rows else None
    return [{"title": "Contact images (Figs. 3a, 7, 9, 13)", "text": text, "table": table,
             "figures": figures}]
