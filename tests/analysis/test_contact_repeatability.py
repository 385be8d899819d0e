"""Repeatability with images (paper Sec. 2.2) on simulated NLRE and TLRE repetitions.

The NLRE: the model loaded to 500 N and unloaded, three times; the TLRE: two passes of load, slide,
release (tests/analysis/sim.py); frames by the simulated camera (tests/analysis/contact_sim.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rigctl.analysis.pipeline import analyse_campaign, analyse_run
from rigctl.analysis.report import write_report
from rigctl.model import Drive, Simulator, build_model
from rigctl.model.noise import NoiseModel
from rigctl.storage.reader import RunReader
from tests.analysis.contact_sim import write_with_frames
from tests.analysis.sim import two_passes

SLOPE = "Isum-Fn slope below 300 N"


def nlre(path: Path, peaks_N: tuple[float, ...], seed: int, **kw: object) -> Path:
    """Load to each of ``peaks_N`` in 5 s, hold 1 s, unload in 5 s, rest 2 s; frames at 10 Hz."""
    t, fn = [0.0, 1.0], [0.0, 0.0]
    for peak in peaks_N:
        for dt, f in ((5.0, peak), (1.0, peak), (5.0, 0.0), (2.0, 0.0)):
            t.append(t[-1] + dt)
            fn.append(f)
    tt = np.array(t)
    res = Simulator(build_model("paper")).run(Drive(tt, np.zeros_like(tt), np.array(fn)))
    NoiseModel().apply(res, np.random.default_rng(seed))
    return write_with_frames(path, res, res.to_measured(), rate_hz=10.0, **kw)  # type: ignore[arg-type]


def _isum_max_in(path: Path, t_a: float, t_b: float) -> float:
    with RunReader(path) as r:
        frames, t, _ = r.frames(0, r.n_frames)
    sel = (t >= t_a) & (t <= t_b)
    return float(frames[sel].reshape(int(sel.sum()), -1).sum(axis=1).max())


def test_three_equal_loadings_repeat_and_a_lower_one_does_not(tmp_path: Path) -> None:
    same = nlre(tmp_path / "same.h5", (500.0, 500.0, 500.0), seed=5)
    ra = analyse_run(same)
    assert len(ra.loadings) == 3
    for lo in ra.loadings:
        assert lo.fn_max_N == pytest.approx(500.0, rel=0.02)
        # max Isum is the largest frame sum of the loading, read here from the frames themselves
        assert lo.isum_max == pytest.approx(_isum_max_in(same, lo.t_start_s, lo.t_end_s), rel=1e-9)
        assert lo.fit.r2 > 0.99 and lo.fit.n >= 20 and lo.fit.slope > 0
    rep = {q.name: q for q in ra.repeatability}
    assert rep["max Isum"].relative_error < 0.0131  # the paper's NLRE: < 1.31 %
    assert rep[SLOPE].relative_error < 0.056        # the paper's: < 5.6 %
    v = np.array(rep["max Isum"].values)
    assert rep["max Isum"].relative_error == pytest.approx(np.max(np.abs(v - v.mean())) / v.mean())

    low = analyse_run(nlre(tmp_path / "low.h5", (500.0, 500.0, 350.0), seed=5))
    q = {q.name: q for q in low.repeatability}["max Isum"]
    assert np.argmin(q.values) == 2  # the lower load has less contact
    assert q.relative_error > 5 * rep["max Isum"].relative_error


@pytest.mark.slow
def test_runs_of_one_protocol_are_repetitions_in_the_campaign(tmp_path: Path) -> None:
    folder = tmp_path / "nlre"
    folder.mkdir()
    for seed in (1, 2, 3):
        nlre(folder / f"nlre{seed}.h5", (500.0,), seed, protocol="NLRE",
             parameters={"fn_N": 500.0})
    nlre(folder / "other.h5", (300.0,), 4, protocol="NLRE", parameters={"fn_N": 300.0})
    ca = analyse_campaign([folder])
    assert len(ca.repeat_groups) == 1  # the 300 N run has no repetition
    g = ca.repeat_groups[0]
    assert g.runs == ("nlre1", "nlre2", "nlre3") and g.parameters == {"fn_N": 500.0}
    q = {x.name: x for x in g.quantities}
    assert set(q) == {"max Isum", SLOPE}  # no pass: no max Ft
    assert q["max Isum"].relative_error < 0.0131 and q[SLOPE].relative_error < 0.056
    assert list(q["max Isum"].values) == [ra.loadings[0].isum_max for ra in ca.runs[:3]]
    index, js = write_report(ca, tmp_path / "rep")
    html = index.read_text()
    assert "Repeatability across runs" in html and "nlre1, nlre2, nlre3" in html
    doc = json.loads(js.read_text())
    assert doc["repeatability"][0]["runs"] == ["nlre1", "nlre2", "nlre3"]
    assert doc["runs"][0]["loadings"][0]["fit_r2"] > 0.99


@pytest.mark.slow
def test_a_tlre_run_has_max_ft_max_isum_and_the_fit_per_pass(tmp_path: Path) -> None:
    res, run = two_passes()
    path = write_with_frames(tmp_path / "tlre.h5", res, run, rate_hz=15.0, protocol="TLRE")
    ra = analyse_run(path)
    assert len(ra.loadings) == 2 and len(ra.mechanics.passes) == 2
    rep = {q.name: q for q in ra.repeatability}
    assert set(rep) == {"max Ft", "max Isum", SLOPE}
    for q in rep.values():
        assert len(q.values) == 2 and q.relative_error < 0.0131
    assert all(r2 > 0.98 for r2 in rep[SLOPE].extra["r2"])
    index, js = write_report(analyse_campaign([path]), tmp_path / "rep")
    html = index.read_text()
    assert "max Isum [grey levels]" in html and f"{SLOPE} [grey levels/N]" in html
    assert "built-in method" not in html  # the values themselves, not a dict's method
    assert ", ".join(f"{v:.4g}" for v in rep["max Isum"].values) in html
    names = [q["name"] for q in json.loads(js.read_text())["runs"][0]["repeatability"]]
    assert names == ["max Ft", "max Isum", SLOPE]
