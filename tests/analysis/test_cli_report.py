"""`rigctl analyse`: report, JSON, a folder as a force sweep."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rigctl.analysis.friction import Coefficient, FrictionCoefficients
from rigctl.analysis.sweep import SweepPoint, summarise
from rigctl.cli.main import main
from rigctl.io.csv_format import write_csv
from tests.analysis.sim import one_pass


@pytest.mark.slow
def test_one_run_report_and_json(tmp_path, capsys):
    res, run = one_pass()
    csv = tmp_path / "run.csv"
    write_csv(csv, run)
    out = tmp_path / "rep"
    assert main(["analyse", str(csv), "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == json.loads((out / "analysis.json").read_text())
    p = doc["runs"][0]["passes"][0]
    assert p["n_cycles"] == len(res.events)
    assert p["friction"]["mu_s_max"] == pytest.approx(0.2, rel=0.02)
    assert len(p["cycles"]) == p["n_cycles"] and len(p["stiffness"]) == p["n_cycles"]
    html = (out / "index.html").read_text()
    for png in ("ft_time.png", "ft_delta_pass1.png", "k_cycles.png"):
        assert (out / png).stat().st_size > 10_000
        assert f'src="{png}"' in html
    assert "mu_s,max" in html and "<script" not in html


@pytest.mark.slow
def test_default_out_folder_next_to_the_run(tmp_path, capsys):
    _, run = one_pass()
    csv = tmp_path / "r1.csv"
    write_csv(csv, run)
    assert main(["analyse", str(csv)]) == 0
    assert (tmp_path / "analysis_r1" / "index.html").is_file()
    assert "report:" in capsys.readouterr().out


@pytest.mark.slow
def test_folder_of_runs_at_three_forces_is_a_sweep(tmp_path, capsys):
    folder = tmp_path / "sweep"
    folder.mkdir()
    for fn in (150.0, 250.0, 350.0):
        _, run = one_pass(fn_N=fn, duration_s=30.0)
        write_csv(folder / f"fn{fn:.0f}.csv", run)
    out = tmp_path / "rep"
    assert main(["analyse", str(folder), "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    sw = doc["sweep"]
    assert [p["fn_N"] for p in sw["points"]] == pytest.approx([150, 250, 350], rel=0.01)
    # the paper model's coefficients do not depend on Fn: recovered at every force
    for p in sw["points"]:
        assert p["friction"]["mu_s_max"] == pytest.approx(0.2, rel=0.02)
        assert p["friction"]["mu_s"]["mean"] == pytest.approx(0.15, rel=0.02)
        assert p["n_stable_cycles"] >= 2
    assert sw["stick_slip_vanishes_below_N"] is None
    assert (out / "sweep_fig10.png").is_file() and (out / "sweep_fig11.png").is_file()
    # runs keep their own figures apart
    assert (out / "fn150_ft_time.png").is_file() and (out / "fn350_ft_time.png").is_file()


def _point(fn: float, n_stable: int, rel: float) -> SweepPoint:
    c = Coefficient(0.1, 0.0, 0.1, 0.1, max(n_stable, 0))
    return SweepPoint("r", 0, fn, FrictionCoefficients(0.2, c, c), 1e6, (1e6,), n_stable, rel)


def test_where_stick_slip_fades_and_vanishes():
    s = summarise([_point(350, 5, 0.45), _point(150, 0, 0.0), _point(200, 3, 0.1),
                   _point(250, 4, 0.4), _point(175, 0, 0.0)])
    assert [p.fn_N for p in s.points] == [150, 175, 200, 250, 350]
    assert s.vanishes_below_N == 200
    assert s.fades_below_N == 250
    s = summarise([_point(150, 4, 0.4), _point(300, 4, 0.42)])
    assert math.isnan(s.vanishes_below_N) and math.isnan(s.fades_below_N)
    assert np.isnan(summarise([_point(150, 0, 0.0), _point(300, 0, 0.0)]).vanishes_below_N)
