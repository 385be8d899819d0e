"""Contact spots by the weighted multi-scale filter (WSM) and their colour superposition (CSI)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.analysis.contact_csi import COLOURS, csi_image, membership, proportions
from rigctl.analysis.contact_spots import WsmSettings, extract_spots

DARK = 8.0


def disks(shape: tuple[int, int], centres: list[tuple[int, int]], r: float) -> np.ndarray:
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    m = np.zeros(shape, bool)
    for cy, cx in centres:
        m |= (yy - cy) ** 2 + (xx - cx) ** 2 <= r * r
    return m


def frame_of(mask: np.ndarray, seed: int, level: float = 120.0, noise: float = 1.5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = DARK + level * mask + rng.normal(0.0, noise, mask.shape)
    return np.clip(np.rint(f), 0, 255).astype(np.uint8)


def test_three_masks_give_known_proportions_and_colours() -> None:
    a = np.zeros((10, 10), bool)
    b = np.zeros_like(a)
    c = np.zeros_like(a)
    a[0, :4] = True          # 4 px: A only -> blue, separation
    b[1, :3] = True          # 3 px: B only -> green, separation
    a[2, :2] = b[2, :2] = True          # 2 px: A B -> sky blue, separation
    c[3, :5] = True          # 5 px: C only -> red, new contact
    a[4, :3] = c[4, :3] = True          # 3 px: A C -> purple, growth
    b[5, :1] = c[5, :1] = True          # 1 px: B C -> yellow, growth
    a[6, :6] = b[6, :6] = c[6, :6] = True  # 6 px: all -> black
    code = membership(a, b, c)
    p = proportions(code)
    assert p.n_contact_px == 24
    assert p.counts == {"blue": 4, "green": 3, "sky blue": 2, "red": 5, "purple": 3, "yellow": 1,
                        "black": 6}
    assert p.proportions == pytest.approx({"contact separation": 9 / 24, "new contact": 5 / 24,
                                           "area growth": 4 / 24, "black-region growth": 6 / 24})
    assert sum(p.proportions.values()) == pytest.approx(1.0)
    img = csi_image(code)
    assert tuple(img[0, 0]) == COLOURS[1] == (0, 0, 255)
    assert tuple(img[3, 0]) == COLOURS[4] == (230, 0, 0)
    assert tuple(img[6, 0]) == (0, 0, 0)
    assert tuple(img[9, 9]) == (255, 255, 255)
    with pytest.raises(ValueError, match="three 2-D masks of one shape"):
        membership(a, b, c[:5])
    assert np.isnan(proportions(np.zeros((3, 3), np.uint8)).proportions["new contact"])


def test_wsm_finds_the_spots_and_no_noise_spots() -> None:
    shape = (80, 100)
    truth = disks(shape, [(15, 20), (40, 50), (60, 80), (20, 75)], 3.5)
    sp = extract_spots(frame_of(truth, 1), DARK)
    assert sp.n_spots == 4
    iou = np.count_nonzero(sp.mask & truth) / np.count_nonzero(sp.mask | truth)
    assert iou > 0.9
    # faint spots (4 noise RMS) are still found; a pure noise field has none
    faint = extract_spots(frame_of(truth, 2, level=6.0), DARK)
    assert faint.n_spots == 4
    assert extract_spots(frame_of(np.zeros(shape, bool), 3), DARK).n_spots == 0
    with pytest.raises(ValueError, match="sum to 1"):
        WsmSettings(weights=(0.5, 0.5, 0.5))


def test_csi_of_three_noisy_frames_recovers_the_masks_proportions() -> None:
    shape = (120, 160)
    rng = np.random.default_rng(7)
    centres = [(int(y), int(x)) for y, x in zip(rng.integers(8, 112, 40), rng.integers(8, 152, 40),
                                                strict=True)]
    first = disks(shape, centres[:30], 3.0)
    middle = disks(shape, centres[5:35], 3.0)
    last = disks(shape, centres[12:40], 3.8)  # the kept spots grow, new ones appear
    want = proportions(membership(first, middle, last)).proportions
    masks = [extract_spots(frame_of(m, s), DARK).mask for s, m in enumerate((first, middle, last))]
    got = proportions(membership(*masks)).proportions
    for k in want:
        assert got[k] == pytest.approx(want[k], abs=0.03), k
    assert sum(got.values()) == pytest.approx(1.0)


def test_wsm_on_the_simulated_camera_matches_its_noise_free_contact() -> None:
    from sim_devices.contact_image import CameraOptics, ContactImageRenderer

    state = (300.0, np.full(10, 0.1), np.zeros(10, bool), 1)
    clean = ContactImageRenderer(CameraOptics(width_px=320, height_px=240, read_noise_rms=0.0))
    noisy = ContactImageRenderer(CameraOptics(width_px=320, height_px=240))
    truth = clean.render(*state) > clean.optics.dark_level
    sp = extract_spots(noisy.render(*state), clean.optics.dark_level)
    iou = np.count_nonzero(sp.mask & truth) / np.count_nonzero(sp.mask | truth)
    assert iou > 0.9
