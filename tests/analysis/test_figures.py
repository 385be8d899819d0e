"""Figures of the analysis report: values equal to four digits are not drawn as a trend."""

from __future__ import annotations

from matplotlib.figure import Figure

from rigctl.analysis.figures_mech import FLAT_HALF_WIDTH, save


def test_a_flat_series_is_drawn_flat_and_a_real_trend_keeps_its_zoom(tmp_path):
    fig = Figure()
    flat, trend = fig.subplots(1, 2)
    flat.plot([1, 2, 3], [1.41301, 1.41302, 1.41303])
    trend.plot([1, 2, 3], [1.0, 1.2, 1.4])
    save(fig, tmp_path, "f.png")
    lo, hi = flat.get_ylim()
    assert hi - lo >= 2 * FLAT_HALF_WIDTH * 1.413 * 0.999
    lo2, hi2 = trend.get_ylim()
    assert hi2 - lo2 < 0.6  # matplotlib's own limits, about 1.0 to 1.4
    assert (tmp_path / "f.png").stat().st_size > 0
