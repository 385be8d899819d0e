"""Contact images that are not clean: truncated grey levels, all-black, saturated and NaN frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.records.contact_intensity import (
    ContactRegion,
    dark_level_of,
    find_contact_region,
    stream_intensity,
)
from rigctl.records.contact_profile import p_density
from rigctl.storage.reader import RunReader
from tests.analysis.test_contact_intensity import write_frames

H, W = 480, 160
C0, C1 = 40, 120  # contact spots in these columns only


def spotted(level: float, sigma: float, quantise: str, n: int = 6, seed: int = 0) -> np.ndarray:
    """Dark field ``level`` + Gaussian read noise, 8 % of the contact columns' pixels 80 brighter."""
    rng = np.random.default_rng(seed)
    f = level + rng.normal(0.0, sigma, (n, H, W))
    spots = np.zeros((n, H, W), dtype=bool)
    spots[:, :, C0:C1] = rng.random((n, H, C1 - C0)) < 0.08
    f += 80.0 * spots
    q = np.floor(f) if quantise == "truncate" else np.rint(f)
    return np.clip(q, 0, 255).astype(np.uint8)


@pytest.mark.parametrize(("level", "quantise"), [(6.8, "truncate"), (6.3, "truncate"),
                                                 (6.8, "round"), (6.0, "round")])
def test_truncated_grey_levels_keep_the_region_and_the_dark_level(
        tmp_path: Path, level: float, quantise: str) -> None:
    frames = spotted(level, 1.0, quantise)
    # truncating 6.8 + noise: the integer median (6) sits 0.3 below the values' mean (6.3); a median
    # dark level then leaves 0.3 x 480 grey levels in every column sum, far above the noise
    dark_mean = float(frames[:, :, :C0].mean())
    path = write_frames(tmp_path / "t.h5", frames, np.arange(frames.shape[0]) / 60.0)
    with RunReader(path) as r:
        reg = find_contact_region(r)
        ci = stream_intensity(r, reg)
    assert (reg.col0, reg.col1) == (C0, C1)
    assert reg.dark_level == pytest.approx(dark_mean, abs=0.03)
    # the dark columns outside the contact carry (almost) nothing of I(x, t)
    dark_cols = frames[:, :, :C0].sum(axis=1) - H * reg.dark_level
    assert np.abs(dark_cols.mean()) < 0.03 * H
    assert np.all(np.isfinite(p_density(ci.profile)))


def test_dark_level_is_the_noise_mean_and_its_rms() -> None:
    rng = np.random.default_rng(4)
    for level, sigma in ((6.0, 1.2), (20.4, 2.0), (3.5, 0.7)):
        px = np.rint(level + rng.normal(0.0, sigma, 200_000)).astype(np.uint8)
        px[:8000] = 150  # 4 % bright contact pixels do not move it
        dark, rms = dark_level_of(px)
        assert dark == pytest.approx(level, abs=0.03)
        assert rms == pytest.approx(np.sqrt(sigma**2 + 1 / 12), rel=0.1)
    assert dark_level_of(np.full(100, 9, np.uint8)) == (9.0, 0.5)  # no noise: the level itself
    with pytest.raises(ValueError, match="no finite pixel"):
        dark_level_of(np.full(4, np.nan))


def test_all_black_and_saturated_frames_get_notes_not_a_crash(tmp_path: Path) -> None:
    frames = spotted(6.0, 1.0, "round", n=8)
    frames[3] = 0                       # the camera sent nothing
    frames[5, 100:110, 60:70] = 255     # a glare: 100 saturated pixels
    t = np.arange(8) / 60.0
    path = write_frames(tmp_path / "bad.h5", frames, t)
    with RunReader(path) as r:
        reg = find_contact_region(r)
        ci = stream_intensity(r, reg, max_bytes=3 * H * W)
    assert (reg.col0, reg.col1) == (C0, C1)
    assert ci.blank is not None and list(np.flatnonzero(ci.blank)) == [3]
    assert np.isnan(ci.isum[3]) and np.isnan(ci.ic[3]) and np.all(np.isnan(ci.profile[3]))
    good = np.delete(np.arange(8), 3)
    np.testing.assert_allclose(ci.isum[good], frames[good].reshape(7, -1).sum(axis=1))
    assert ci.saturated_px is not None and ci.saturated_px[5] == 100
    assert np.count_nonzero(ci.saturated_px) == 1
    notes = ci.quality_notes()
    assert len(notes) == 2
    assert notes[0].startswith("1 of 8 frames all black") and f"t = {t[3]:.3f} s" in notes[0]
    assert notes[1].startswith("1 of 8 frames have saturated pixels")


def test_only_black_frames_is_a_clear_error(tmp_path: Path) -> None:
    path = write_frames(tmp_path / "black.h5", np.zeros((3, H, W), np.uint8), np.arange(3.0))
    with RunReader(path) as r, pytest.raises(DataError, match="none of the 3 frames"):
        find_contact_region(r)


class _FloatFrames:
    """A reader of float frames (another rig's camera) in memory."""

    path = Path("float-frames")

    def __init__(self, frames: np.ndarray) -> None:
        self._f = frames
        self.n_frames = int(frames.shape[0])

    def frames(self, a: int, b: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.arange(self.n_frames) / 60.0
        return self._f[a:b], t[a:b], np.arange(self.n_frames)[a:b]


def test_nan_pixels_make_their_frame_nan_with_a_note() -> None:
    frames = spotted(6.0, 1.0, "round", n=5).astype(np.float32)
    frames[2, 7, 9] = np.nan
    reader = _FloatFrames(frames)
    reg = find_contact_region(reader)  # type: ignore[arg-type]
    assert (reg.col0, reg.col1) == (C0, C1)  # the NaN frame is not a probe
    ci = stream_intensity(reader, ContactRegion(C0, C1, reg.dark_level))  # type: ignore[arg-type]
    assert ci.nonfinite is not None and list(np.flatnonzero(ci.nonfinite)) == [2]
    assert np.isnan(ci.isum[2]) and np.isfinite(np.delete(ci.isum, 2)).all()
    assert ci.saturated_px is None  # float pixels: no known full scale
    assert any("NaN or infinite" in n for n in ci.quality_notes())
