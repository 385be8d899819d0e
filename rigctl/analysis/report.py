"""The analysis report: ``DIR/index.html`` (Jinja2 template, PNG figures) and ``DIR/analysis.json``.

The page shows, per run, what could not be done and why, the friction and stiffness per pass, the
repeatability, the figures and the cycle tables; a campaign with several normal forces gets the
force-sweep section first. ``analysis.json`` holds every number (NaN written as ``null``).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import jinja2
import numpy as np

from rigctl.analysis import figures_mech, figures_sweep
from rigctl.analysis.contact_report import contact_sections
from rigctl.analysis.friction import Coefficient
from rigctl.analysis.pipeline import CampaignAnalysis, RunAnalysis
from rigctl.analysis.repeatability import Repeated
from rigctl.analysis.sweep import SweepSummary
from rigctl.io.atomic import atomic_text_writer
from rigctl.io.json_values import jsonable
from rigctl.records.progress import SILENT, Progress

_ENV = jinja2.Environment(
    loader=jinja2.PackageLoader("rigctl.analysis", "templates"),
    autoescape=jinja2.select_autoescape(["html", "j2"]),
    undefined=jinja2.StrictUndefined,
)


def fmt(x: object, digits: int = 4) -> str:
    """A number for the page: 4 significant digits, '-' for NaN/None."""
    if x is None:
        return "-"
    if isinstance(x, float | np.floating):
        v = float(x)
        return "-" if not math.isfinite(v) else f"{v:.{digits}g}"
    return str(x)


def _pm(c: Coefficient) -> str:
    if c.n == 0:
        return "-"
    return f"{c.mean:.4f} &plusmn; {c.std:.4f} (n={c.n})"


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name) or "run"


def _repeat_rows(qs: Sequence[Repeated]) -> list[dict[str, str]]:
    """Table rows of repeated quantities; a fit's R^2 and largest deviation from its line."""
    rows = []
    for q in qs:
        detail = ""
        if "r2" in q.extra:
            detail = "R^2 " + ", ".join(fmt(v, 4) for v in q.extra["r2"]) + "; off the line by " \
                + ", ".join(fmt(100 * v, 3) for v in q.extra.get("fit_error", [])) + " % at most"
        rows.append({"name": q.name + (f" [{q.unit}]" if q.unit else ""),
                     "per": ", ".join(fmt(v) for v in q.values),
                     "error": fmt(100 * q.relative_error, 3) + " %", "detail": detail})
    return rows


def _run_context(ra: RunAnalysis, folder: Path, prefix: str) -> dict[str, Any]:
    m = ra.mechanics
    s = ra.source
    figures: list[str] = []
    if m.passes:
        figures.append(figures_mech.ft_time(m.passes, folder, f"{prefix}ft_time.png"))
        for rec, st in zip(m.passes, m.stiffness, strict=True):
            figures.append(figures_mech.ft_delta(
                rec, st, folder, f"{prefix}ft_delta_pass{rec.pas.index + 1}.png"))
        figures.append(figures_mech.k_cycles(m.passes, m.stiffness, folder,
                                             f"{prefix}k_cycles.png"))
    passes = []
    cycle_tables = []
    for rec, fc, st in zip(m.passes, m.friction, m.stiffness, strict=True):
        k = np.array([c.k.k_N_per_m for c in st])
        stable_k = Coefficient.of(k[rec.stable] / 1e6)
        passes.append({
            "index": rec.pas.index + 1, "fn": fmt(rec.pas.fn_N),
            "v": fmt(rec.pas.velocity_m_s * 1e6), "cycles": rec.cycles.n,
            "mu_s_max": fmt(fc.mu_s_max), "mu_s": _pm(fc.mu_s), "mu_k": _pm(fc.mu_k),
            "k1": fmt(k[0] / 1e6) if k.size else "-",
            "k_stable": "-" if stable_k.n == 0 else
            f"{stable_k.mean:.4g} &plusmn; {stable_k.std:.2g} (n={stable_k.n})",
            "delta_valid": f"{100 * float(np.mean(rec.delta_valid)):.0f} %",
        })
        rows = []
        for j, c in enumerate(rec.cycles.rows()):
            rows.append([c["cycle"], c["stage"], fmt(c["t_start_s"], 6), fmt(c["t_peak_s"], 6),
                         fmt(c["t_end_s"], 6), fmt(c["peak_N"]), fmt(c["trough_N"]),
                         fmt(c["drop_N"]), fmt(c["stick_s"]),
                         fmt(float(c["slip_m"]) * 1e6), fmt(c["fn_N"]),
                         fmt(st[j].k.k_N_per_m / 1e6)])
        cycle_tables.append({"index": rec.pas.index + 1, "rows": rows})
    rep = _repeat_rows(ra.repeatability)
    frames = "none" if s.frames is None else (
        f"{s.frames.n_frames} of {s.frames.width_px} x {s.frames.height_px} px at "
        f"{fmt(s.frames.measured_rate_hz)} Hz")
    # the passes' markup (&plusmn;) is ours, not data: mark it safe, escape the rest
    for p in passes:
        for key in ("mu_s", "mu_k", "k_stable"):
            p[key] = jinja2.utils.markupsafe.Markup(p[key])
    return {
        "name": ra.name, "anchor": _slug(ra.name), "file": str(s.path),
        "protocol": f"{s.protocol or '-'} {json.dumps(s.parameters) if s.parameters else ''}",
        "status": s.status or "(CSV)",
        "samples": f"{s.run.n_samples} over {s.run.duration_s:.1f} s at "
                   f"{s.run.sample_rate_hz:.0f} Hz",
        "frames": frames, "notes": ra.notes, "passes": passes, "repeatability": rep,
        "figures": figures,
        "sections": contact_sections(ra.contact, ra.contact_absent, m, folder, prefix),
        "cycle_tables": cycle_tables,
    }


def _sweep_context(sw: SweepSummary, folder: Path) -> dict[str, Any]:
    rows = [{
        "run": p.run, "pass": p.pass_index + 1, "fn": fmt(p.fn_N),
        "mu_s_max": fmt(p.friction.mu_s_max), "mu_s": fmt(p.friction.mu_s.mean),
        "mu_k": fmt(p.friction.mu_k.mean), "k1": fmt(p.k1_N_per_m / 1e6),
        "n_stable": p.n_stable, "rel": fmt(p.relative_drop, 3), "im1": fmt(p.im1),
    } for p in sw.points]
    return {
        "vanishes": "-" if not math.isfinite(sw.vanishes_below_N) else f"{sw.vanishes_below_N:.0f} N",
        "fades": "-" if not math.isfinite(sw.fades_below_N) else f"{sw.fades_below_N:.0f} N",
        "rows": rows, "notes": list(sw.notes),
        "figures": figures_sweep.sweep_figures(sw, folder),
    }


def write_report(result: CampaignAnalysis, out_dir: str | Path,
                 progress: Progress = SILENT) -> tuple[Path, Path]:
    """Write ``index.html``, its PNGs and ``analysis.json`` into ``out_dir`` (created)."""
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    runs: list[dict[str, Any]] = []
    several = len(result.runs) > 1
    with progress.bar(len(result.runs), "figures", "run") as bar:
        for ra in result.runs:
            prefix = f"{_slug(ra.name)}_" if several else ""
            runs.append(_run_context(ra, folder, prefix))
            bar.update()
    sweep = _sweep_context(result.sweep, folder) if result.sweep is not None else None
    names = ", ".join(r.name for r in result.runs[:3]) + (" ..." if len(result.runs) > 3 else "")
    title = f"Analysis of {names}" if result.runs else "Analysis"
    html = _ENV.get_template("report.html.j2").render(
        title=title, created=datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        campaign_notes=result.notes, sweep=sweep, runs=runs,
        repeat_groups=[{"protocol": g.protocol + (f" {json.dumps(g.parameters)}" if g.parameters
                                                  else ""),
                        "runs": ", ".join(g.runs), "quantities": _repeat_rows(g.quantities)}
                       for g in result.repeat_groups],
    )
    index = folder / "index.html"
    with atomic_text_writer(index) as fh:
        fh.write(html)
    js = folder / "analysis.json"
    with atomic_text_writer(js) as fh:
        json.dump(jsonable(result.to_dict()), fh, indent=1, allow_nan=False)
    return index, js


def campaign_json(result: CampaignAnalysis) -> str:
    """The JSON document of a campaign (as ``analysis.json``)."""
    return json.dumps(jsonable(result.to_dict()), indent=1, allow_nan=False)


def run_names(runs: Sequence[RunAnalysis]) -> list[str]:
    return [r.name for r in runs]
