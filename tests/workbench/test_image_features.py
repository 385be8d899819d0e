"""The model's stress distribution P(i, t) against the contact images (image_features.py).

Simulated TLREs with frames: the model's run (normal loading, rest, slide, release under load)
rendered by the simulated camera (tests/analysis/contact_sim.py) and written to a run file; the
truth is known. The rig here has presliding, which the compared model (``paper``) lacks: a real rig
is never exactly the model, and the force features then leave p_slope loosely determined.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from rigctl.cli.main import main
from rigctl.data import MeasuredRun
from rigctl.model import Drive, NoiseModel, Simulator, build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.records.feature_info import IMAGE_FEATURES
from rigctl.storage.reader import RunReader
from rigctl.workbench.compare import Comparison, compare
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.report import write_compare_report
from tests.analysis.contact_sim import write_with_frames

PAPER = ModelChoice("paper")
# load 0 -> 300 N in 1 s, rest 2 s, slide 200 um at 10 um/s, release under load, apart
T_S = [0.0, 1.0, 3.0, 23.0, 24.0, 25.0]
X_M = [0.0, 0.0, 0.0, 2e-4, 2e-4, 2e-4]
FN_N = [0.0, 300.0, 300.0, 300.0, 0.0, 0.0]


@functools.lru_cache(maxsize=4)
def _run_file(folder: Path, p_slope: float, effects: tuple[str, ...]) -> Path:
    model = build_model("paper", effects=list(effects), params={"p_slope": p_slope})
    res = Simulator(model).run(Drive(np.array(T_S), np.array(X_M), np.array(FN_N)))
    NoiseModel().apply(res, np.random.default_rng(1))
    name = f"tlre_s{p_slope:g}_{'_'.join(effects) or 'paper'}.h5"
    return write_with_frames(folder / name, res, res.to_measured(), protocol="tlre")


def _measured(path: Path) -> MeasuredRun:
    with RunReader(path) as reader:
        return reader.to_measured()


def _without_images(ds: Dataset) -> Dataset:
    return dataclasses.replace(
        ds, runs=tuple(dataclasses.replace(r, image=None) for r in ds.runs))


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("image_features")


@pytest.fixture(scope="module")
def rig_run(folder: Path) -> Path:
    return _run_file(folder, 0.9, ("presliding",))


@pytest.fixture(scope="module")
def with_images(rig_run: Path) -> Comparison:
    return compare([_measured(rig_run)], PAPER)


@pytest.mark.parametrize("p_slope", [0.5, 0.9])
def test_the_images_read_the_initial_stress_tilt(folder: Path, p_slope: float) -> None:
    ds = prepare_dataset([_measured(_run_file(folder, p_slope, ()))])
    img = ds.runs[0].image
    assert img is not None, ds.notes
    assert img.tilt == pytest.approx(p_slope, abs=0.05)  # read from light only, not the model
    assert 0.0 < img.tilt_sigma < 0.05
    # back end below its stable share, front end above (Fig. 13a, P_linear)
    assert img.r_meas[0] < 0.8 < 1.2 < img.r_meas[-1]
    assert abs(img.var) < 4 * img.var_sigma  # the stable stage's P barely moves (Fig. 13c)
    # the model's P(i, t), read over the same frames from its stage: exactly its p_slope
    ev = evaluate(ds, PAPER.with_values({"p_slope": p_slope}))
    assert ev.images is not None
    assert ev.images[0]["p_tilt_initial"] == pytest.approx(p_slope, abs=1e-9)
    assert ev.images[0]["p_var_stable"] == 0.0
    off = evaluate(ds, PAPER.with_values({"p_slope": p_slope - 0.2}))
    assert off.score.feature_error["p_tilt_initial"] > 4.0 * ev.score.feature_error[
        "p_tilt_initial"]


@pytest.mark.slow
def test_the_image_feature_lowers_the_uncertainty_of_p_slope(
    with_images: Comparison, rig_run: Path
) -> None:
    without = compare([_measured(rig_run)], PAPER,
                      dataset=_without_images(with_images.dataset))

    def p_slope(c: Comparison) -> tuple[float, float]:
        row = next(r for r in c.parameter_rows() if r["name"] == "p_slope")
        return float(row["value"]), float(row["sigma"])

    v_img, s_img = p_slope(with_images)
    _, s_frc = p_slope(without)
    assert "p_tilt_initial" in with_images.fit.feature_error
    assert "p_tilt_initial" not in without.fit.feature_error
    assert s_img < 0.5 * s_frc, (s_img, s_frc)
    assert abs(v_img - 0.9) < max(3.0 * s_img, 0.02), (v_img, s_img)


@pytest.mark.slow
def test_compare_json_report_and_text_show_the_image_feature(
    with_images: Comparison, rig_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    js = with_images.to_json()
    assert set(IMAGE_FEATURES) <= set(js["feature_errors"])
    row = js["image_features"][0]
    assert row["n_frames"] > 100 and len(row["r_measured"]) == 10
    assert row["model"]["p_tilt_initial"] == pytest.approx(
        next(p["value"] for p in js["parameters"] if p["name"] == "p_slope"), rel=1e-6)
    page = write_compare_report(with_images, tmp_path / "report").read_text()
    assert "Stress distribution against the contact images" in page
    assert (tmp_path / "report" / "image_ratios.png").stat().st_size > 10_000
    assert main(["model", "compare", str(rig_run), "--no-fit"]) == 0
    text = capsys.readouterr().out
    assert "initial-stage stress tilts" in text
    assert main(["model", "compare", str(rig_run), "--no-fit", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["image_features"][0]["name"] == str(rig_run)


@pytest.mark.slow
def test_a_run_without_frames_compares_as_before(with_images: Comparison, rig_run: Path) -> None:
    """The same samples without frames (a CSV-like run): no image entry, the same residual vector
    as the run file with its image feature removed, a note saying so; with frames every other
    feature's error is unchanged and E only gains the image terms."""
    run = _measured(rig_run)
    run.source = "tlre.csv"
    ds_csv = prepare_dataset([run])
    assert ds_csv.runs[0].image is None
    assert any("no image feature" in n and "tlre.csv" in n for n in ds_csv.notes)
    ev_csv = evaluate(ds_csv, PAPER)
    ev_h5 = evaluate(_without_images(with_images.dataset), PAPER)
    assert np.array_equal(ev_csv.score.vector, ev_h5.score.vector)
    assert ev_csv.score.error == ev_h5.score.error
    assert not set(IMAGE_FEATURES) & set(ev_csv.score.feature_error)
    ev_img = evaluate(with_images.dataset, PAPER)
    fe, fe0 = ev_img.score.feature_error, ev_csv.score.feature_error
    assert {k: fe[k] for k in fe0} == fe0
    n0, n1 = len(fe0), len(fe)
    assert n1 == n0 + len(IMAGE_FEATURES)
    expect = math.sqrt((n0 * ev_csv.score.error**2
                        + sum(fe[k] ** 2 for k in IMAGE_FEATURES)) / n1)
    assert ev_img.score.error == pytest.approx(expect, rel=1e-12)
    assert ev_img.score.vector.size == ev_csv.score.vector.size + len(IMAGE_FEATURES)
    assert float(ev_img.score.vector @ ev_img.score.vector) == pytest.approx(n1 * ev_img.score.error**2)


@pytest.mark.slow
def test_a_model_without_the_stress_evolution_is_told_by_the_images(folder: Path) -> None:
    path = _run_file(folder, 0.9, ())
    classic = compare([_measured(path)], ModelChoice("classic"), identify=False)
    assert classic.fit.feature_error["p_tilt_initial"] > 20.0  # uniform P: tilt 0 against 0.89
    assert any(d.startswith("initial-stage stress tilts") and "the model 0.000" in d
               for d in classic.discrepancies), classic.discrepancies
    paper = compare([_measured(path)], PAPER, identify=False)
    assert not any("stress tilts" in d for d in paper.discrepancies)
