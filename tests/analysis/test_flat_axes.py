"""Report figures: a flat series is drawn flat, but an image or an inverted axis is left alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rigctl.analysis.figures_mech import save


def test_flat_series_widened_images_and_inverted_axes_kept(tmp_path: Path) -> None:
    fig = Figure()
    flat, image, inverted = fig.subplots(1, 3)
    flat.plot([0, 1, 2], [300.0, 300.001, 300.0])
    image.imshow(np.zeros((120, 108, 3), dtype=np.uint8))
    inverted.plot([0, 1], [10.0, 20.0])
    inverted.invert_yaxis()
    before_image, before_inverted = image.get_ylim(), inverted.get_ylim()
    save(fig, tmp_path, "f.png")
    lo, hi = flat.get_ylim()
    assert hi - lo > 0.04 * 300.0  # widened to +-2.5 % of the level, not zoomed onto 0.001 N
    assert image.get_ylim() == before_image  # all 120 rows shown
    assert inverted.get_ylim() == before_inverted
    assert (tmp_path / "f.png").stat().st_size > 0
