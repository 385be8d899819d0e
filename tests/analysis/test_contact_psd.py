"""Surface PSD (Fig. 4d): Sq from the spectrum, isotropy, and the simulated camera's surface."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.analysis.surface_psd import surface_psd
from sim_devices.contact_image import CameraOptics, ContactImageRenderer
from sim_devices.rough_surface import SQ_BOSS_M, rough_surface


def test_an_isotropic_surface_of_known_sq_gives_that_sq() -> None:
    sq = []
    for seed in range(4):
        h = rough_surface(512, 512, 1e-6, sq_m=1.5e-6, hurst=0.7, rolloff_wavelength_m=30e-6,
                          seed=seed)
        psd = surface_psd(h, 1e-6)
        # the window weighs the middle of a finite map: a few % of sampling scatter per map
        assert psd.sq_m == pytest.approx(1.5e-6, rel=0.05)
        assert psd.anisotropy < 1.15
        sq.append(psd.sq_m)
    assert np.mean(sq) == pytest.approx(1.5e-6, rel=0.02)
    # self-affine between roll-off and cut-off: C ~ f^-2(1+H)
    band = (psd.f_per_m > 1 / 20e-6) & (psd.f_per_m < 1 / 5e-6)
    slope = np.polyfit(np.log(psd.f_per_m[band]), np.log(psd.c_m4[band]), 1)[0]
    assert slope == pytest.approx(-2 * 1.7, abs=0.3)


def test_a_sine_puts_its_power_at_its_frequency_and_is_anisotropic() -> None:
    n, px = 128, 1e-6
    x = np.arange(n) * px
    h = 2e-6 * np.sin(2 * np.pi * x / 16e-6)[None, :] * np.ones((n, 1))
    psd = surface_psd(h, px, n_bins=30)
    assert psd.f_per_m[np.nanargmax(psd.c_m4)] == pytest.approx(1 / 16e-6, rel=0.15)
    assert psd.sq_m == pytest.approx(2e-6 / np.sqrt(2), rel=0.05)
    assert psd.anisotropy > 10


def test_a_stretched_surface_is_flagged_anisotropic() -> None:
    h = rough_surface(256, 1024, 1e-6, rolloff_wavelength_m=50e-6, seed=1)[:, ::4]
    assert surface_psd(h, 1e-6).anisotropy > 3


def test_the_simulated_cameras_surface_meets_its_specification() -> None:
    r = ContactImageRenderer(CameraOptics(width_px=640, height_px=480))
    psd = surface_psd(r.height_m, r.pixel_m)
    assert psd.sq_m == pytest.approx(SQ_BOSS_M, rel=0.03)  # Sq 3.024 um (Sec. 2.1)
    assert abs(psd.sq_m - 3e-6) < 0.1e-6
    assert psd.anisotropy < 1.15  # isotropic


@pytest.mark.parametrize(("h", "px", "msg"), [
    (np.zeros((4, 4)), 1e-6, "at least 8 x 8"),
    (np.full((16, 16), np.nan), 1e-6, "NaN"),
    (np.zeros((16, 16)), 0.0, "must be positive"),
])
def test_bad_height_maps_are_named(h: np.ndarray, px: float, msg: str) -> None:
    with pytest.raises(ValueError, match=msg):
        surface_psd(h, px)
