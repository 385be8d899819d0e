"""Contact-image analyses of simulated runs with camera frames, where the truth is known.

The frames are the simulated camera's (tests/analysis/contact_sim.py): in the initial stage the model's
stress distribution is a ramp (the back end carries less) and the back-end elements that slide lose
contact; from the first slip on it is uniform (docs/model.md, sim_devices/contact_image.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rigctl.analysis.contact_csi import CATEGORIES
from rigctl.analysis.figures_contact import isum_fit
from rigctl.analysis.pipeline import RunAnalysis, analyse_campaign, analyse_run
from rigctl.analysis.report import write_report
from rigctl.model import Drive, Simulator, build_model
from rigctl.model.noise import NoiseModel
from rigctl.storage.convert import write_measured_run
from tests.analysis.contact_sim import write_with_frames
from tests.analysis.sim import one_pass


@pytest.fixture(scope="module")
def sim_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    res, run = one_pass(duration_s=20.0)
    return write_with_frames(tmp_path_factory.mktemp("contact") / "sim.h5", res, run)


@pytest.fixture(scope="module")
def analysed(sim_file: Path) -> RunAnalysis:
    return analyse_run(sim_file)


def test_the_back_end_unloads_as_ft_rises_in_the_initial_stage(analysed: RunAnalysis) -> None:
    ca = analysed.contact
    assert ca is not None and analysed.contact_absent == ""
    pc = ca.passes[0]
    ini = pc.p_initial
    assert len(ini) == 4
    ft = [s.ft_N for s in ini]
    assert ft == sorted(ft) and ft[0] < 1.0 and ft[-1] > 40.0
    back = np.array([s.p_k[:2].sum() for s in ini])  # the back fifth of the contact
    # falls while the back end slides and separates; near the threshold the middle separates too
    # and the normalised back share may rise a little again, but stays far below its start
    assert back[1] < back[0] and back[2] < back[1]
    assert np.all(back[2:] < 0.5 * back[0])
    front = np.array([s.p_k[-2:].sum() for s in ini])
    assert front[-1] > front[0]
    for s in ini:  # P(k) sums to 1, P(x) has mean 1
        assert s.p_k.sum() == pytest.approx(1.0)
        assert s.p_x.mean() == pytest.approx(1.0)


def test_the_stable_stress_varies_little_and_is_near_uniform(analysed: RunAnalysis) -> None:
    assert analysed.contact is not None
    pc = analysed.contact.passes[0]
    st = pc.p_stable
    assert len(st) == 3 and pc.stable_cycle is not None
    p = np.array([s.p_k for s in st])
    assert np.max(np.abs(p - p[0])) < 0.01  # "changes little in the whole interface" (Fig. 7c)
    ini = np.array([s.p_k for s in pc.p_initial])
    assert np.max(np.abs(ini - ini[0])) > 5 * np.max(np.abs(p - p[0]))
    # the model's stable P is uniform: the image's P(k) follows it up to the surface's own texture
    assert np.all(np.abs(p[0] - 0.1) < 0.05)


def test_csi_proportions_sum_to_1_and_change_between_the_stages(analysed: RunAnalysis) -> None:
    assert analysed.contact is not None
    csi = {c.stage: c for c in analysed.contact.passes[0].csi}
    assert set(csi) == {"initial", "stable"}
    for c in csi.values():
        assert sum(c.props.proportions.values()) == pytest.approx(1.0)
        assert set(c.props.proportions) == set(CATEGORIES)
        assert c.ft_N[0] < c.ft_N[1] < c.ft_N[2]
    ini, st = csi["initial"].props.proportions, csi["stable"].props.proportions
    # Sec. 3.3: contact separates at the back end as Ft grows in the initial stage; in the stable
    # stage the spots persist (the black region dominates)
    assert ini["contact separation"] > 3 * st["contact separation"]
    assert st["black-region growth"] > ini["black-region growth"]
    assert st["black-region growth"] > 0.8


def test_im_falls_from_the_initial_to_the_stable_stage(analysed: RunAnalysis) -> None:
    assert analysed.contact is not None
    pc = analysed.contact.passes[0]
    im = np.array([m.im for m in pc.im])
    assert len(im) == analysed.mechanics.passes[0].cycles.n and np.all(np.isfinite(im))
    assert all(m.n_frames > 0 for m in pc.im)
    assert np.all(im[1:] < im[0])  # Fig. 7d
    assert np.ptp(im[1:]) < 0.02 * im[1]  # stable: almost unchanged
    assert analysed.im1(0) == im[0]


def test_isum_is_linear_in_fn_below_300_N_on_a_simulated_nlre(tmp_path: Path) -> None:
    t = np.array([0.0, 1.0, 6.0, 7.0, 12.0, 13.0])
    fn = np.array([0.0, 0.0, 500.0, 500.0, 0.0, 0.0])
    res = Simulator(build_model("paper")).run(Drive(t, np.zeros_like(t), fn))
    NoiseModel().apply(res, np.random.default_rng(3))
    path = write_with_frames(tmp_path / "nlre.h5", res, res.to_measured(), rate_hz=10.0)
    ra = analyse_run(path)
    ca = ra.contact
    assert ca is not None and ca.passes == []
    a, _, r2, n = isum_fit(ca.fn_frames_N, ca.intensity.isum, ca.ft_frames_N)
    assert a > 0 and r2 > 0.99 and n > 30


@pytest.mark.slow
def test_the_report_has_the_contact_section(sim_file: Path, tmp_path: Path) -> None:
    index, js = write_report(analyse_campaign([sim_file]), tmp_path / "rep")
    html = index.read_text()
    assert "Contact images" in html and "Absent" not in html
    for png in ("isum.png", "p_xt_pass1.png", "p_bins_pass1.png", "csi_pass1.png"):
        assert (tmp_path / "rep" / png).stat().st_size > 10_000
        assert f'src="{png}"' in html
    doc = json.loads(js.read_text())["runs"][0]["contact"]
    assert doc["passes"][0]["CSI"][0]["stage"] == "initial"
    assert len(doc["passes"][0]["P_initial"][0]["P_k"]) == 10
    rows = (tmp_path / "rep" / "contact_frames.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,isum,ic,fn_N,ft_N,P1") and len(rows) == doc["frames"] + 1


@pytest.mark.slow
def test_a_run_without_frames_says_the_section_is_absent_and_why(tmp_path: Path) -> None:
    _, run = one_pass(duration_s=20.0)
    path = write_measured_run(tmp_path / "nocam.h5", run)
    ra = analyse_run(path)
    assert ra.contact is None and "no camera stream" in ra.contact_absent
    assert np.isnan(ra.im1(0))
    index, js = write_report(analyse_campaign([path]), tmp_path / "rep")
    assert "Absent: the run has no camera stream" in index.read_text()
    assert "no camera stream" in json.loads(js.read_text())["runs"][0]["contact"]["absent"]
