"""HTML reports of ``model compare`` and ``model diagnose`` (with PNG figures) in a folder."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path

from rigctl.records.feature_info import FEATURES
from rigctl.workbench import plots
from rigctl.workbench.compare import Comparison
from rigctl.workbench.diagnose import Diagnosis
from rigctl.workbench.ranking import VerdictKind

_STYLE = """<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}
table{border-collapse:collapse;font-size:0.9em}td,th{border:1px solid #ccc;padding:3px 8px}
th{background:#f3f3f3}img{max-width:100%;border:1px solid #eee;margin:0.5em 0}
.bad{color:#b00}</style>"""


def _fmt(x: object) -> str:
    if isinstance(x, float):
        if not math.isfinite(x):
            return "-"
        return f"{x:.4g}"
    return html.escape(str(x))


def _table(header: list[str], rows: Sequence[Sequence[object]]) -> str:
    out = ["<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{_fmt(c)}</td>" for c in r) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _comparison_sections(cmp: Comparison, folder: Path, *, prefix: str = "",
                         title: str | None = None, anchor: str | None = None) -> list[str]:
    """The HTML of one model against the measurement; its PNGs are ``folder/<prefix><name>.png``
    (a distinct ``prefix`` per section keeps two models' figures apart in one folder). ``title``
    replaces the heading's "Model <label>"; ``anchor`` wraps the section in ``<section id=...>``."""
    res = cmp.results
    ev = cmp.evaluation.events
    figs = [
        plots.overlay_time(cmp.runs, res, cmp.dataset, ev, folder / f"{prefix}overlay_time.png"),
        plots.loops(cmp.runs, res, cmp.dataset, ev, folder / f"{prefix}loops.png"),
        plots.features(cmp.dataset, ev, folder / f"{prefix}features.png"),
        plots.residual_heatmap(cmp.rmap, folder / f"{prefix}residual_map.png"),
    ]
    feat_rows = [
        [FEATURES[name].phrase, cmp.fit.feature_error.get(name, math.nan), fe.rms, fe.mean,
         fe.unit, fe.n]
        for name, fe in cmp.errors.items()
    ]
    par_rows = [
        [r["name"], r["value"], r["sigma"] if r["sigma"] is not None else math.nan, r["unit"],
         "yes" if r["fitted"] else "", "" if r["determined"] or not r["fitted"] else
         "NOT determined by these data"]
        for r in cmp.parameter_rows()
    ]
    disc = "".join(f"<li>{html.escape(s)}</li>" for s in cmp.discrepancies) or \
        "<li>no structured discrepancy above the scatter</li>"
    heading = title if title is not None else f"Model {cmp.fit.choice.label()}"
    body = [
        f"<h2>{html.escape(heading)}: error {cmp.fit.error:.3g}</h2>",
        "<p>Error E: RMS over features of block-averaged event residuals in units of the "
        "measurement's event-to-event scatter (about 1 = within the scatter; docs/workbench.md)."
        "</p>",
        "<h3>Where it fails</h3><ul>" + disc + "</ul>",
        f'<img src="{figs[3].name}">',
        *_pattern_figure(cmp, folder, prefix),
        "<h3>Model against measurement</h3>",
        f'<img src="{figs[0].name}"><img src="{figs[1].name}"><img src="{figs[2].name}">',
        "<h3>Per-feature error</h3>",
        _table(["feature", "z error", "RMS residual", "mean residual", "unit", "events"],
               feat_rows),
        "<h3>Parameters</h3>",
        _table(["parameter", "value", "1-sigma", "unit", "fitted", "note"], par_rows),
    ]
    body += _image_section(cmp, folder, prefix)
    if anchor is not None:
        body = [f'<section id="{html.escape(anchor)}">', *body, "</section>"]
    return body


def _pattern_figure(cmp: Comparison, folder: Path, prefix: str) -> list[str]:
    """The residual's periods (docs/identification.md, "Structure that is not a straight line"), drawn
    against where they repeat: only when the map found one."""
    if not cmp.rmap.patterns:
        return []
    png = plots.periodic_patterns(cmp.rmap.patterns, folder / f"{prefix}periodic.png")
    return ["<p>Not a straight line: the residual against where it repeats, each run less its "
            "straight line, with the fitted sinusoid (each run its own phase).</p>",
            f'<img src="{png.name}">']


def _image_section(cmp: Comparison, folder: Path, prefix: str) -> list[str]:
    """The model's stress distribution against the contact images (docs/reading-records.md,
    "Contact images"): per run the image features and the per-part ratios, or why a run has none."""
    rows = cmp.image_rows()
    with_frames = [r for r in rows if "absent" not in r]
    out = ["<h3>Stress distribution against the contact images</h3>"]
    for r in rows:
        if "absent" in r:
            out.append(f"<p>{html.escape(str(r['name']))}: no image feature "
                       f"({html.escape(str(r['absent']))}).</p>")
    if not with_frames:
        return out
    png = plots.image_ratios(with_frames, folder / f"{prefix}image_ratios.png")
    table = [
        [r["name"], FEATURES[name].phrase, r[name], r[f"{name}_sigma"],
         r["model"].get(name, math.nan), cmp.fit.feature_error.get(name, math.nan)]
        for r in with_frames for name in ("p_tilt_initial", "p_var_stable")
    ]
    out += [
        "<p>r(k): the load share of part k in the initial stage over its share in the stable "
        "stage, read from the frames where the part's light is equal (equal light, equal "
        "pressure); the tilt of r(k) along x is p_slope for the model's P_linear.</p>",
        f'<img src="{png.name}">',
        _table(["run", "feature", "measured", "scatter", "model", "z error"], table),
    ]
    return out


def _notes(notes: Sequence[str]) -> list[str]:
    """What was read from the data and how (no probes, probes over range, a rig description,
    units to check, ...): the notes ``compare`` and ``diagnose`` print, each one item."""
    if not notes:
        return []
    items = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
    return [f"<h3>Notes on the data</h3><ul>{items}</ul>"]


def _page(title: str, body: list[str]) -> str:
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            f"</title>{_STYLE}</head><body><h1>{html.escape(title)}</h1>\n"
            + "\n".join(body) + "</body></html>")


def write_compare_report(cmp: Comparison, folder: str | Path) -> Path:
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    body = [f"<p>Runs: {html.escape(', '.join(cmp.dataset.names))} "
            f"({cmp.dataset.n_events} slip events)</p>", *_notes(cmp.dataset.notes)]
    body += _comparison_sections(cmp, out)
    path = out / "index.html"
    path.write_text(_page("rigctl model compare", body), encoding="utf-8")
    return path


def write_diagnose_report(diag: Diagnosis, cmp: Comparison, folder: str | Path,
                          final_cmp: Comparison | None = None) -> Path:
    """``cmp`` is the comparison of the diagnosed (first) model, for overlays and the map.

    ``final_cmp`` (with ``--auto``) is the comparison of ``diag.final_model``, the model after the
    last added effect: it gets its own section (overlays, loops, features, residual map with
    ``final_``-prefixed PNGs) after the base model's. It is left out when no effect was added.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    r0 = diag.first
    rank_png = plots.ranking(r0.ranking, r0.model.error, out / "ranking.png")
    rows = [[s.effect, s.error, s.error_reduction, s.delta_bic,
             "yes" if s.significant else "", s.explains] for s in r0.ranking]
    v = r0.verdict
    verdict = html.escape(v.verdict)
    if v.candidates:
        verdict += " (" + html.escape(", ".join(v.candidates)) + ")"
    body = [
        f"<p>Runs: {html.escape(', '.join(diag.dataset.names))} ({diag.dataset.n_events} slip "
        f"events); protocols present: {html.escape(', '.join(diag.protocols) or 'none')}</p>",
        *_notes(diag.dataset.notes),
        f"<h2>Verdict: {verdict}</h2>",
    ]
    if v.unexplained:
        body.append(f"<p><b>{html.escape(v.unexplained)}</b></p>")
    if v.suggest:
        body.append(f"<p>To tell them apart: {html.escape(v.suggest)}</p>")
    body += [
        f'<img src="{rank_png.name}">',
        _table(["effect", "error", "error reduction", "delta BIC", "significant", "explains"],
               rows),
    ]
    last = diag.rounds[-1].verdict
    if len(diag.rounds) > 1 and last.kind is VerdictKind.INDISTINGUISHABLE:
        body.append(f"<p><b>Stopped: the data cannot decide between "
                    f"{html.escape(' and '.join(last.candidates))}.</b> To tell them apart: "
                    f"{html.escape(last.suggest or '')}</p>")
        if last.runs:
            body.append("<pre>" + "\n".join(html.escape(str(r["command"])) for r in last.runs)
                        + "</pre>")
    if len(diag.steps) > 1:
        fall = plots.error_fall([s.model for s in diag.steps], [s.error for s in diag.steps],
                                out / "error_fall.png")
        body += ["<h2>Adding effects</h2>", f'<img src="{fall.name}">',
                 _table(["step", "model", "added", "error", "delta BIC", "note"],
                        [[s.index, s.model, s.added or "", s.error,
                          s.delta_bic if s.delta_bic is not None else math.nan, s.note]
                         for s in diag.steps])]
    added = [s.added for s in diag.steps if s.added]
    if final_cmp is None or not added:
        body += _comparison_sections(cmp, out)
    else:
        body.append('<p>Below: the base model, then the model after the last added effect '
                    '(<a href="#final-model">jump there</a>).</p>')
        body += _comparison_sections(cmp, out, title=f"Base model ({cmp.fit.choice.label()})",
                                     anchor="base-model")
        body += _comparison_sections(final_cmp, out, prefix="final_",
                                     title=f"After adding {', '.join(added)}",
                                     anchor="final-model")
    path = out / "index.html"
    path.write_text(_page("rigctl model diagnose", body), encoding="utf-8")
    return path
