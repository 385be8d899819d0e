"""`rigctl model compare` and `rigctl model diagnose` end to end on CSV campaigns."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rigctl.cli.main import main
from rigctl.io.csv_format import write_csv
from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign, write_campaign


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("damped")
    model = build_model("paper", effects=["interface_damping"], params={"mu_s": 0.16})
    write_campaign(simulate_campaign(model, "tlre", seed=21, duration_scale=0.6), folder)
    return folder


def test_compare_json_gives_the_error_per_feature_and_parameters(campaign, capsys):
    assert main(["model", "compare", str(campaign), "--json"]) == 0
    cap = capsys.readouterr()
    assert "identifying paper" in cap.err  # progress on stderr, with --json too
    out = json.loads(cap.out)
    assert out["model"] == "paper" and out["error"] > 0
    assert {"peak_N", "trough_N", "ring_N", "stick_s"} <= set(out["feature_errors"])
    fe = out["feature_errors"]["peak_N"]
    assert set(fe) == {"z", "rms", "mean", "unit", "n"} and fe["unit"] == "N"
    names = {p["name"] for p in out["parameters"]}
    assert {"mu_s", "mu_k", "kts_N_per_m"} <= names
    assert isinstance(out["discrepancies"], list)
    # where it fails: by stage, by phase, by time (tenths of each run) and against covariates
    assert set(out["residual_by_stage"]) == {"initial", "stable"}
    assert set(out["residual_by_phase"]) == {"stick", "slip"}
    assert all(len(v) == 10 for v in out["residual_by_time"].values())
    assert all({"feature", "covariate", "amplitude_z", "t"} <= set(t)
               for t in out["residual_trends"])


@pytest.mark.slow
def test_compare_with_the_missing_effect_added_has_a_smaller_error(campaign, capsys):
    main(["model", "compare", str(campaign), "--json"])
    without = json.loads(capsys.readouterr().out)["error"]
    main(["model", "compare", str(campaign), "--json", "--effects", "interface_damping"])
    with_effect = json.loads(capsys.readouterr().out)["error"]
    assert with_effect < 0.5 * without


@pytest.mark.slow
def test_diagnose_json_follows_the_contract_and_writes_a_report(campaign, tmp_path, capsys):
    report = tmp_path / "rep"
    code = main(["model", "diagnose", str(campaign), "--json", "--workers", "2",
                 "--candidates", "interface_damping,wear,probe_drift", "--report", str(report)])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert {"base", "baseline_error", "ranking", "verdict", "candidates", "suggest"} <= set(out)
    assert "steps" not in out  # only with --auto
    assert isinstance(out["base"], str) and isinstance(out["baseline_error"], float)
    assert isinstance(out["candidates"], list) and out["suggest"] is None
    for row in out["ranking"]:
        assert isinstance(row["effect"], str) and isinstance(row["explains"], str)
        assert isinstance(row["significant"], bool)
        for key in ("error", "error_reduction", "delta_bic"):
            assert isinstance(row[key], float), (key, row)
    # the verdict's set leads; then the other fitted sets, significant first, each by delta BIC;
    # then the sets only screened (docs/workbench.md, "JSON output")
    rows = out["ranking"]
    fitted = [r for r in rows if not r["explains"].startswith("screened only")]
    assert rows[:len(fitted)] == fitted
    assert fitted[0]["effect"] == out["verdict"]
    assert fitted[1:] == sorted(fitted[1:], key=lambda r: (not r["significant"], r["delta_bic"]))
    assert out["verdict"] == "interface_damping"
    top = out["ranking"][0]
    assert set(top) == {"effect", "error", "error_reduction", "delta_bic", "significant",
                        "explains"}
    assert top["effect"] == "interface_damping" and top["significant"]
    assert top["error_reduction"] >= 0.5
    html = (report / "index.html").read_text()
    for png in ("ranking.png", "overlay_time.png", "loops.png", "residual_map.png"):
        assert (report / png).stat().st_size > 5000
        assert png in html


def test_bad_data_is_one_line_naming_the_file(tmp_path, capsys):
    run = simulate_campaign(build_model("paper"), "tlre", seed=1, duration_scale=0.3)[0]
    run.ft_N = run.ft_N.copy()
    run.ft_N[50] = np.inf
    path = tmp_path / "broken.csv"
    # write NaN-free first, then corrupt the text so the reader sees it
    run.ft_N[50] = 0.0
    write_csv(path, run)
    lines = path.read_text().splitlines()
    header_at = next(i for i, line in enumerate(lines) if line.startswith("t_s"))
    cells = lines[header_at + 60].split(",")
    cells[3] = "nan"
    lines[header_at + 60] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    assert main(["model", "compare", str(path)]) == 2
    err = capsys.readouterr().err
    assert "broken.csv" in err and len(err.strip().splitlines()) == 1


def test_unknown_effect_and_missing_path_are_usage_errors(campaign, tmp_path, capsys):
    assert main(["model", "compare", str(campaign), "--effects", "magic"]) == 2
    assert "unknown effect 'magic'" in capsys.readouterr().err
    assert main(["model", "diagnose", str(tmp_path / "nowhere")]) == 2
    assert "nowhere" in capsys.readouterr().err


@pytest.mark.slow
def test_compare_searches_with_the_workers_asked(campaign, monkeypatch, capsys):
    """`--workers N` reaches the search (N worker processes evaluate its points); the default is
    the CPUs; 0 is refused."""
    import rigctl.workbench.compare as compare_module
    from rigctl.workbench.parallel import default_workers

    asked: list[int] = []
    search = compare_module.search_model

    def spy(dataset, choice, **kw):
        asked.append(kw.get("workers", 1))
        return search(dataset, choice, **kw)

    monkeypatch.setattr(compare_module, "search_model", spy)
    assert main(["model", "compare", str(campaign), "--json", "--workers", "2"]) == 0
    assert main(["model", "compare", str(campaign), "--json"]) == 0
    assert asked == [2, default_workers()]
    capsys.readouterr()
    assert main(["model", "compare", str(campaign), "--workers", "0"]) == 2
    assert "--workers must be at least 1" in capsys.readouterr().err



def test_json_keeps_stdout_for_the_result_and_quiet_silences_the_progress(campaign, capsys):
    assert main(["model", "compare", str(campaign), "--json", "--no-fit", "--quiet"]) == 0
    cap = capsys.readouterr()
    json.loads(cap.out)  # stdout is the JSON alone
    assert cap.err == ""
