"""Isum (Eq. 1), I(x,t) and P(x,t) on synthetic frames with known answers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rigctl.analysis.contact_stress import im_cycles, p_at_forces
from rigctl.analysis.stiffness import NAN_SLOPE, CycleStiffness
from rigctl.data import DataError
from rigctl.records.contact_intensity import (
    ContactRegion,
    bin_matrix,
    find_contact_region,
    stream_intensity,
)
from rigctl.records.contact_profile import p_bins, p_density
from rigctl.storage import RunWriter
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from rigctl.storage.reader import RunReader

H, W = 40, 160
C0, C1 = 30, 130  # the contact: 100 columns
DARK = 10


def ramp_frame(scale: int = 1, reverse: bool = False) -> np.ndarray:
    """Dark field; contact columns j = 0..99 at DARK + scale (2 j + 1): I(x) proportional to x."""
    f = np.full((H, W), DARK, np.uint8)
    j = np.arange(C1 - C0)
    col = DARK + scale * (2 * j + 1)
    f[:, C0:C1] = (col[::-1] if reverse else col)[None, :]
    return f


def write_frames(path: Path, frames: np.ndarray, t: np.ndarray) -> Path:
    td = np.arange(0.0, float(t[-1]) + 1.0, 1e-3)
    cols = {"t_s": td, "x_stage_m": np.zeros_like(td), "fn_N": np.full_like(td, 100.0),
            "ft_N": td.copy(), "d1_m": np.zeros_like(td), "d2_m": np.zeros_like(td)}
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=frames.shape[1], width_px=frames.shape[2])
    with RunWriter(path, RunDescription(protocol="sim"), daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        w.append_frames(frames, t, np.arange(frames.shape[0]))
    return path


def test_bin_matrix_keeps_every_column_whole() -> None:
    m = bin_matrix(3, 2)
    np.testing.assert_allclose(m, np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]))
    np.testing.assert_allclose(bin_matrix(437, 100).sum(axis=1), 1.0, rtol=1e-6)


def test_a_known_gradient_gives_the_known_p(tmp_path: Path) -> None:
    frames = np.stack([ramp_frame(1), ramp_frame(1, reverse=True), np.full((H, W), DARK, np.uint8)])
    p = write_frames(tmp_path / "ramp.h5", frames, np.array([0.0, 0.5, 1.0]))
    with RunReader(p) as r:
        region = find_contact_region(r)
        assert (region.col0, region.col1, region.dark_level) == (C0, C1, DARK)
        ci = stream_intensity(r, region, max_bytes=H * W)  # one frame per chunk
    # Eq. 1: the plain sum of the grey levels; Ic without the dark field
    np.testing.assert_allclose(ci.isum, frames.reshape(3, -1).sum(axis=1))
    np.testing.assert_allclose(ci.ic, ci.isum - H * W * DARK)
    x = ci.x_centres
    p_x = p_density(ci.profile)
    np.testing.assert_allclose(p_x[0], 2 * x, rtol=1e-5)        # I ~ x, normalised: P = 2 x
    np.testing.assert_allclose(p_x[1], 2 * (1 - x), rtol=1e-5)  # back end bright
    assert np.all(np.isnan(p_x[2]))                              # no contact: no P
    k = np.arange(1, 11)
    np.testing.assert_allclose(p_bins(ci.profile)[0], (2 * k - 1) / 100, rtol=1e-5)
    assert np.nansum(p_bins(ci.profile)[1]) == pytest.approx(1.0)


def test_back_end_on_the_right_flips_x(tmp_path: Path) -> None:
    p = write_frames(tmp_path / "ramp.h5", ramp_frame(1)[None], np.array([0.0]))
    with RunReader(p) as r:
        ci = stream_intensity(r, ContactRegion(C0, C1, DARK, back_end_left=False), n_bins=50)
    np.testing.assert_allclose(p_density(ci.profile)[0], 2 * (1 - ci.x_centres), rtol=1e-5)


def test_dark_frames_only_is_a_clear_error(tmp_path: Path) -> None:
    p = write_frames(tmp_path / "dark.h5", np.full((2, H, W), DARK, np.uint8), np.array([0.0, 1.0]))
    with RunReader(p) as r, pytest.raises(DataError, match="no contact is visible"):
        find_contact_region(r)
    with RunReader(p) as r, pytest.raises(DataError, match="exceed the frame width"):
        stream_intensity(r, ContactRegion(0, W + 5, DARK))


def test_p_bins_need_parts_that_divide_the_bins() -> None:
    with pytest.raises(ValueError, match="do not split into 10"):
        p_bins(np.ones((1, 64)))


def _stiff(cycle: int, window: tuple[float, float]) -> CycleStiffness:
    return CycleStiffness(cycle, "stable", NAN_SLOPE, (NAN_SLOPE,), window, 0.0, 1.0)


def test_im_is_the_mean_contact_intensity_over_each_k_window(tmp_path: Path) -> None:
    scales = np.array([1, 2, 3, 4, 3, 2])
    frames = np.full((6, H, W), DARK, np.uint8)
    frames[:, :, C0:C1] += (20 * scales).astype(np.uint8)[:, None, None]
    p = write_frames(tmp_path / "im.h5", frames, np.arange(6) * 0.1)
    with RunReader(p) as r:
        ci = stream_intensity(r, ContactRegion(C0, C1, DARK))
    ic = H * 100 * 20 * scales
    np.testing.assert_allclose(ci.ic, ic)
    im = im_cycles(ci, [_stiff(1, (0.05, 0.25)), _stiff(2, (0.32, 0.38)),
                        _stiff(3, (math.nan, math.nan))])
    assert im[0].im == pytest.approx(ic[1:3].mean()) and im[0].n_frames == 2
    assert im[1].n_frames == 0 and im[1].im == pytest.approx(np.interp(0.35, ci.t_s, ic))
    assert math.isnan(im[2].im)
    # P at chosen forces: the first frame of the window whose Ft reaches the target
    ft = np.array([0.0, 10.0, 20.0, 30.0, 40.0, 50.0])
    snaps = p_at_forces(ci, ft, 0.05, 0.45, [0.0, 25.0, 45.0, 99.0])
    assert [s.frame for s in snaps] == [1, 3]  # 45 N is after the window, 99 N never reached
