"""Force sweep with contact images (paper Sec. 4.1, Fig. 11c-d): Im(1) against Fn and K(1)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rigctl.analysis.pipeline import analyse_campaign
from rigctl.analysis.report import write_report
from rigctl.io.csv_format import write_csv
from tests.analysis.contact_sim import write_with_frames
from tests.analysis.sim import one_pass

FORCES_N = (150.0, 250.0, 350.0)


@pytest.mark.slow
def test_im1_against_fn_and_k1_when_the_runs_have_frames(tmp_path: Path) -> None:
    folder = tmp_path / "sweep"
    folder.mkdir()
    for fn in FORCES_N:
        res, run = one_pass(fn_N=fn, duration_s=20.0)
        write_with_frames(folder / f"fn{fn:.0f}.h5", res, run, rate_hz=20.0)
    ca = analyse_campaign([folder])
    sw = ca.sweep
    assert sw is not None and [round(p.fn_N) for p in sw.points] == [150, 250, 350]
    # each point's Im(1) is its run's own, from the contact analysis of that run
    for p, ra in zip(sw.points, ca.runs, strict=True):
        assert ra.contact is not None
        assert p.im1 == ra.contact.passes[0].im[0].im and np.isfinite(p.im1)
    im1 = np.array([p.im1 for p in sw.points])
    assert np.all(np.diff(im1) > 0)  # more load, more contact (Fig. 11c)
    assert not any("camera frames" in n for n in sw.notes)
    index, js = write_report(ca, tmp_path / "rep")
    doc = json.loads(js.read_text())["sweep"]
    assert [p["Im1"] for p in doc["points"]] == pytest.approx(list(im1))
    assert (tmp_path / "rep" / "sweep_fig11.png").stat().st_size > 20_000
    assert "no camera frames" not in index.read_text()


@pytest.mark.slow
def test_a_sweep_without_frames_says_no_camera_frames(tmp_path: Path) -> None:
    folder = tmp_path / "csv"
    folder.mkdir()
    for fn in FORCES_N[:2]:
        _, run = one_pass(fn_N=fn, duration_s=20.0)
        write_csv(folder / f"fn{fn:.0f}.csv", run)
    ca = analyse_campaign([folder])
    assert ca.sweep is not None
    assert all(np.isnan(p.im1) for p in ca.sweep.points)
    assert any(n.startswith("no camera frames: Im(1)") for n in ca.sweep.notes)
    index, js = write_report(ca, tmp_path / "rep")
    assert "no camera frames: Im(1) against Fn" in index.read_text()
    doc = json.loads(js.read_text())["sweep"]
    assert all(p["Im1"] is None for p in doc["points"])
    assert any("no camera frames" in n for n in doc["notes"])
