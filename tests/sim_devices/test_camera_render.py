"""The contact image: a PSD rough surface, contact spots from the model's pressure, Isum vs Fn."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.errors import DeviceStateError, DeviceTimeout
from rigctl.model import Drive, Simulator, build_model
from sim_devices.camera_sim import SimCamera
from sim_devices.contact_image import CameraOptics, ContactImageRenderer
from sim_devices.rough_surface import SQ_BOSS_M, rough_surface
from sim_devices.virtual_rig import VirtualRig

UNIFORM = np.full(10, 0.1)
NOT_SLIDING = np.zeros(10, dtype=bool)


def isum(frame: np.ndarray) -> float:
    """Summed intensity of the image (Han et al. 2022, Section 2.2)."""
    return float(frame.astype(np.float64).sum())


def test_surface_has_the_boss_roughness_and_a_self_affine_spectrum() -> None:
    n, pixel = 256, 10e-6
    h = rough_surface(n, n, pixel, hurst=0.8, rolloff_wavelength_m=0.5e-3, seed=3)
    assert float(np.sqrt(np.mean(h**2))) == pytest.approx(SQ_BOSS_M, rel=1e-9)
    # radially averaged PSD falls as q^-2(1+H) between roll-off and cut-off
    power = np.abs(np.fft.fft2(h)) ** 2
    q = np.hypot(*np.meshgrid(np.fft.fftfreq(n, pixel), np.fft.fftfreq(n, pixel)))
    bands = np.geomspace(1 / 0.4e-3, 1 / 40e-6, 12)
    mids, levels = [], []
    for lo, hi in zip(bands[:-1], bands[1:], strict=True):
        sel = (q >= lo) & (q < hi)
        mids.append(np.sqrt(lo * hi))
        levels.append(power[sel].mean())
    slope = np.polyfit(np.log(mids), np.log(levels), 1)[0]
    assert slope == pytest.approx(-2 * (1 + 0.8), abs=0.25)
    again = rough_surface(n, n, pixel, hurst=0.8, rolloff_wavelength_m=0.5e-3, seed=3)
    np.testing.assert_array_equal(h, again)  # seeded: generated identically


def test_isum_rises_with_fn_nearly_linearly_below_300_N() -> None:
    r = ContactImageRenderer(CameraOptics(read_noise_rms=0.0))
    fns = np.arange(0.0, 801.0, 25.0)
    sums = np.array([isum(r.render(fn, UNIFORM, NOT_SLIDING, 1)) for fn in fns])
    assert np.all(np.diff(sums) > 0)
    low = fns <= 300.0
    fit = np.polyfit(fns[low], sums[low], 1)
    resid = sums[low] - np.polyval(fit, fns[low])
    r2 = 1.0 - resid.var() / sums[low].var()
    assert r2 > 0.99  # Han et al. 2022, Fig. 3a: approximately linear below 300 N


def test_back_end_darkens_as_ft_rises_in_the_initial_stage() -> None:
    res = Simulator(build_model()).run(Drive.constant(300.0, 1e-5, 11.0))
    r = ContactImageRenderer(CameraOptics(read_noise_rms=0.0))
    cols = r.boss_columns()
    back = slice(cols.start, cols.start + 2 * r.boss_px // 5)  # elements 0-3
    front = slice(cols.stop - 3 * r.boss_px // 10, cols.stop)  # elements 7-9
    means = []
    for ft in (0.5, 30.0, 50.0):
        i = int(np.argmax(res.ft_N >= ft))
        assert res.stage[i] == 0
        img = r.render(300.0, res.p_elements[i], res.sliding_elements[i], 0).astype(float)
        means.append((img[:, back].mean(), img[:, front].mean()))
    dark = r.optics.dark_level
    (b0, f0), (b1, f1), (b2, f2) = ((b - dark, f - dark) for b, f in means)
    assert b2 < b1 < 0.8 * b0 and b2 < 0.5 * b0  # the back end separates progressively
    assert f2 == pytest.approx(f0, rel=0.1) and f1 == pytest.approx(f0, rel=0.1)


def test_rendering_is_fast_and_sizes_are_bounded() -> None:
    r = ContactImageRenderer()
    p = np.linspace(0.05, 0.15, 10)
    p /= p.sum()
    r.render(300.0, p, NOT_SLIDING, 0)
    t0 = time.perf_counter()
    for _ in range(50):
        frame = r.render(300.0, p, NOT_SLIDING, 0)
    ms = (time.perf_counter() - t0) / 50 * 1e3
    assert frame.shape == (240, 240) and frame.dtype == np.uint8
    assert ms < 10.0, f"{ms:.2f} ms per 240 x 240 frame"
    big = ContactImageRenderer(CameraOptics(width_px=640, height_px=480))
    assert big.render(300.0, p, NOT_SLIDING, 0).shape == (480, 640)
    for w, h in ((641, 480), (640, 481), (8, 8)):
        with pytest.raises(ValueError):
            CameraOptics(width_px=w, height_px=h)


def test_sim_camera_frames_follow_the_rig_clock_and_faults() -> None:
    rig = VirtualRig()  # manual clock: frames exist only once the rig reaches them
    cam = SimCamera(rig, buffer_frames=10)
    with pytest.raises(DeviceStateError):
        cam.read_frame(0.1)
    cam.start()
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout):
        cam.read_frame(0.2)
    assert time.monotonic() - t0 < 1.0
    rig.advance_to(1.0)
    frames = [cam.read_frame(0.5) for _ in range(3)]
    # 60 frames exist; the buffer keeps the newest 10: the first read reports the loss
    assert [f.seq for f in frames] == [50, 51, 52]
    assert frames[0].dropped_before == 50 and cam.frames_dropped == 50
    dt_ns = np.diff([f.t_monotonic_ns for f in frames])
    np.testing.assert_allclose(dt_ns, 1e9 / 60, atol=2)  # manual clock maps 1:1 to host time
    cam.faults.stuck = True
    a, b = cam.read_frame(0.5), cam.read_frame(0.5)
    np.testing.assert_array_equal(a.image, b.image)
    cam.faults.stuck = False
    cam.faults.drop_pct = 50.0
    seqs = [cam.read_frame(0.5).seq for _ in range(3)]
    assert seqs[-1] - seqs[0] > 2 and cam.frames_dropped > 50
    cam.faults.drop_pct = 0.0
    cam.faults.silent = True
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout):
        cam.read_frame(0.3)
    assert time.monotonic() - t0 < 1.0
    cam.stop()
    cam.close()
