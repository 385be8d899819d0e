"""`model diagnose --auto` (the error falls step by step), plug-ins by file, the run's time limit.

The campaign hides two effects at once, so ``--auto`` has to add one, re-identify, find the other,
add it, and then stop because nothing significant is left.
"""

from __future__ import annotations

import json

import pytest

from rigctl.cli.main import main
from rigctl.io.load import load_runs
from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign, write_campaign
from rigctl.workbench.compare import compare
from rigctl.workbench.diagnose import Diagnosis, DiagnosisStep, Round
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.ranking import Verdict, score_candidate
from rigctl.workbench.report import write_diagnose_report
from tests.workbench.hidden import PLUGIN

CANDIDATES = "interface_damping,probe_drift,wear,contact_degradation"


@pytest.fixture(scope="module")
def two_effects(tmp_path_factory):
    folder = tmp_path_factory.mktemp("two_effects")
    model = build_model("paper", effects=["interface_damping", "probe_drift"],
                        params={"mu_s": 0.145, "mu_k": 0.1},
                        effect_params={"interface_damping": {"c_N_s_per_m": 40.0},
                                       "probe_drift": {"rate_m_per_s": 8e-8}})
    write_campaign(simulate_campaign(model, "tlre", seed=61, duration_scale=0.7), folder)
    return folder


@pytest.mark.slow
def test_auto_adds_both_hidden_effects_and_the_error_falls(two_effects, tmp_path, capsys):
    report = tmp_path / "auto"
    code = main(["model", "diagnose", str(two_effects), "--auto", "--json", "--workers", "2",
                 "--candidates", CANDIDATES, "--report", str(report)])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    steps = out["steps"]
    assert steps[0]["added"] is None and steps[0]["error"] == pytest.approx(out["baseline_error"])
    added = [s["added"] for s in steps[1:]]
    assert sorted(added) == ["interface_damping", "probe_drift"], steps
    errors = [s["error"] for s in steps]
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[-1] < 0.25 * errors[0]
    assert out["final_model"] == steps[-1]["model"]
    assert all(s["delta_bic"] < -10 for s in steps[1:])
    html = (report / "index.html").read_text()
    assert (report / "error_fall.png").stat().st_size > 5000 and "error_fall.png" in html
    # the report shows the base model and, next to it, the model after the last added effect
    base_title = f"Base model ({steps[0]['model']}): error {errors[0]:.3g}"
    final_title = f"After adding {', '.join(added)}: error {errors[-1]:.3g}"
    assert base_title in html and final_title in html
    assert html.index(base_title) < html.index(final_title)
    final_part = html[html.index('<section id="final-model">'):]
    for png in ("overlay_time.png", "loops.png", "features.png", "residual_map.png"):
        base_png, final_png = report / png, report / f"final_{png}"
        assert f'src="{png}"' in html and f'src="final_{png}"' in final_part
        assert final_png.stat().st_size > 5000
        assert final_png.read_bytes() != base_png.read_bytes()  # the final model's own figure


@pytest.mark.slow
def test_a_diagnosis_that_added_nothing_has_no_final_model_section(two_effects, tmp_path):
    runs = load_runs([two_effects])
    dataset = prepare_dataset(runs)
    cmp = compare(runs, ModelChoice("paper"), identify=False, dataset=dataset)
    score = score_candidate("wear", cmp.fit.error, cmp.fit.error, dataset.n_events, 1)
    score.explains = "nothing (no improvement)"
    diag = Diagnosis(dataset, [Round(cmp.fit, [score], Verdict("none", [], None), {}, [])],
                     steps=[DiagnosisStep(0, cmp.fit.choice.label(), None, cmp.fit.error, None)])
    # a final comparison handed over anyway is not shown twice: nothing was added
    html = write_diagnose_report(diag, cmp, tmp_path, final_cmp=cmp).read_text()
    assert f"Model paper: error {cmp.fit.error:.3g}" in html
    assert "final-model" not in html and "After adding" not in html and "Base model" not in html
    assert not list(tmp_path.glob("final_*"))
    assert (tmp_path / "overlay_time.png").stat().st_size > 5000


@pytest.mark.slow
def test_auto_prints_the_error_at_each_step(two_effects, capsys):
    assert main(["model", "diagnose", str(two_effects), "--auto", "--workers", "2",
                 "--candidates", CANDIDATES]) == 0
    out = capsys.readouterr().out
    table = out[out.index("\nerror at each step"):].strip().splitlines()[1:]
    steps = [line for line in table if line.strip()[:1].isdigit()]
    assert len(steps) == 3, out
    assert table[-1].strip() == "stopped: nothing significant left"
    assert all("error" in line for line in steps)
    assert "+ interface_damping" in out and "+ probe_drift" in out
    assert "%" in steps[1] and "%" in steps[2]  # the fall relative to the previous step


PLUGIN_CANDIDATES = "force_sensor_drift,wear,probe_drift"


@pytest.fixture(scope="module")
def drifting_sensor(tmp_path_factory):
    folder = tmp_path_factory.mktemp("drifting")
    plugin = folder / "sensor_drift.py"
    plugin.write_text(PLUGIN)
    from rigctl.model.plugins import load_effect_file

    (cls,) = load_effect_file(plugin)
    model = build_model("paper", effects=[cls], params={"mu_s": 0.155, "mu_k": 0.105},
                        effect_params={"force_sensor_drift": {"rate_N_per_s": -0.04}})
    data = folder / "runs"
    write_campaign(simulate_campaign(model, "long_run", seed=62, duration_scale=0.4), data)
    return data, plugin


@pytest.mark.slow
def test_a_plugin_file_takes_part_on_the_command_line(drifting_sensor, capsys):
    data, plugin = drifting_sensor
    assert main(["model", "diagnose", str(data), "--json", "--workers", "2",
                 "--effect-file", str(plugin), "--candidates", PLUGIN_CANDIDATES]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] == "force_sensor_drift", out["ranking"]
    assert out["ranking"][0]["error_reduction"] >= 0.5
    main(["model", "compare", str(data), "--json", "--effect-file", str(plugin)])
    without = json.loads(capsys.readouterr().out)["error"]
    main(["model", "compare", str(data), "--json", "--effect-file", str(plugin),
          "--effects", "force_sensor_drift"])
    with_it = json.loads(capsys.readouterr().out)
    assert with_it["error"] < 0.5 * without
    assert with_it["effects"] == ["force_sensor_drift"]


def test_max_time_ends_the_run_with_the_model_it_has_and_says_so(two_effects, capsys):
    import time

    t0 = time.monotonic()
    code = main(["model", "diagnose", str(two_effects), "--auto", "--candidates", CANDIDATES,
                 "--workers", "1", "--max-time", "1", "--json"])
    took = time.monotonic() - t0
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["time_limited"].startswith("the run's time limit ended")
    assert out["final_model"].startswith("paper")
    assert took < 60.0  # the limit, one evaluation and the report; not a full run


def test_max_time_ends_a_ranking_too(two_effects, capsys):
    """Without --auto the ranking is one step of the same selection, under the same limit. The
    limit (1 s) is a fraction of the ranking's own time (about 5 s on the 2-core machine): at 4 s
    a ranking made faster ended before its limit."""
    code = main(["model", "diagnose", str(two_effects), "--candidates", CANDIDATES,
                 "--workers", "1", "--max-time", "1", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["time_limited"].startswith("the run's time limit ended")
    assert out["base"].startswith("paper")


@pytest.mark.parametrize(("extra", "says"), [
    (["--max-time", "-1"], "--max-time must be 0"),
    (["--auto", "--max-time", "-1"], "--max-time must be 0"),
    (["--auto", "--max-time", "nan"], "--max-time must be 0"),
])
def test_max_time_is_checked_before_any_fit(two_effects, capsys, extra, says):
    code = main(["model", "diagnose", str(two_effects), "--candidates", "wear", *extra])
    assert code == 2 and says in capsys.readouterr().err
