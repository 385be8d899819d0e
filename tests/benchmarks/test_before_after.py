"""The pure parts of benchmarks/before_after.py: reading a benchmark's JSON, its figures, the ratios."""

from __future__ import annotations

import json
from dataclasses import asdict

import pytest

from benchmarks.before_after import HEADLINES, Figure, compare, figure, format_rows, parse_output
from benchmarks.bench_compare import format_table, report
from benchmarks.bench_live_view import Report
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice

RATE = Figure("rate", "a.rate", True)
LAG = Figure("lag", "rig-1x.lag_s", False)


def test_parse_output_skips_what_comes_before_the_json() -> None:
    assert parse_output('warming up\n{\n "a": {"rate": 2}\n}\n') == {"a": {"rate": 2}}
    assert parse_output('[{"case": "rig-1x"}]') == [{"case": "rig-1x"}]
    with pytest.raises(ValueError, match="no JSON"):
        parse_output("Traceback (most recent call last):\n")


def test_figure_follows_keys_and_cases_and_gives_none_for_what_is_missing() -> None:
    cases = [{"case": "rig-1x", "lag_s": 0.25}, {"case": "rig-10x", "lag_s": 1.0}]
    assert figure(cases, "rig-10x.lag_s") == 1.0
    assert figure({"a": {"rate": 3}}, "a.rate") == 3.0
    assert figure({"a": {"rate": None}}, "a.rate") is None  # a NaN written as null
    assert figure({"a": {"rate": True}}, "a.rate") is None
    assert figure({"a": 1.0}, "a.rate") is None
    assert figure(cases, "rig-2x.lag_s") is None
    assert figure(None, "a.rate") is None  # a failed run


def test_compare_takes_ratios_pair_by_pair() -> None:
    old = [{"a": {"rate": 100.0}}, {"a": {"rate": 50.0}}, None, {"a": {"rate": 0.0}}]
    new = [{"a": {"rate": 110.0}}, {"a": {"rate": 45.0}}, {"a": {"rate": 70.0}}, {"a": {"rate": 5.0}}]
    (row,) = compare([RATE], old, new)
    # the pair with a failed old run and the one with old = 0 give no ratio
    assert row.ratios == pytest.approx([1.1, 0.9])
    assert row.old_median == 50.0 and row.new_median == pytest.approx(57.5)


def test_format_rows_prints_medians_and_the_ratio_range() -> None:
    old = [[{"case": "rig-1x", "lag_s": 0.2}], [{"case": "rig-1x", "lag_s": 0.4}]]
    new = [[{"case": "rig-1x", "lag_s": 0.1}], [{"case": "rig-1x", "lag_s": 0.6}]]
    text = format_rows("acquisition", compare([LAG, RATE], old, new), 2)
    assert "| lag | lower | 0.3 | 0.35 | 1.000 | 0.500-1.500 |" in text
    assert "| rate | higher | - | - | - | - |" in text


def test_the_live_view_figures_name_fields_of_its_report() -> None:
    doc = json.loads(json.dumps({**asdict(Report()), "rss_growth_mb": 0.0, "_process": {"cpu_s": 1.0}}))
    assert all(figure(doc, f.path) is not None for f in HEADLINES["live_view"])


def test_the_compare_figures_name_fields_of_its_report() -> None:
    fit = FitResult(ModelChoice("paper"), 3.5, {}, ("mu_s",), n_evaluations=412)
    res = report("k168_v42_60s.csv", 120001, 36, 2, 0.05, 40.0, 70.0, fit)
    doc = json.loads(json.dumps({**res, "_process": {"cpu_s": 1.0}}))
    assert all(figure(doc, f.path) is not None for f in HEADLINES["compare"])
    assert doc["compare_in_evaluations"] == 800.0
    assert "NOT met" in format_table(res)  # 40 s against the 30 s target


def test_the_workbench_figures_name_fields_of_its_timing(monkeypatch) -> None:
    from types import SimpleNamespace

    from benchmarks import bench_workbench as bw

    def fake_diagnose(ds, choice, *, workers, progress):
        progress("  screened a: 1.5 (score 3, best at the off, 20 evaluations) [1/1]")
        progress("  fitted a: 2 -> 1 in 3 s [1/1]")
        return SimpleNamespace(first=SimpleNamespace(ranking=[1], verdict=SimpleNamespace(
            verdict="a")))

    run = SimpleNamespace(duration_s=40.0, n_samples=100)
    monkeypatch.setattr(bw, "simulate_campaign", lambda *a, **k: [run])
    monkeypatch.setattr(bw, "prepare_dataset", lambda runs: SimpleNamespace(n_events=3))
    monkeypatch.setattr(bw, "diagnose", fake_diagnose)
    doc = json.loads(json.dumps({"timing": bw.timing(2), "_process": {"cpu_s": 1.0}}))
    assert all(figure(doc, f.path) is not None for f in HEADLINES["workbench"])
    assert doc["timing"]["screened"] == 1 and doc["timing"]["fitted"] == 1
