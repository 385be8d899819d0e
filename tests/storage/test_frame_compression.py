"""Camera frames: every compression reads back bit-identical, and the size estimate matches a run.

The size test records 2 s of the simulated camera's 640 x 480 contact images at 60 Hz (rendered by
its own renderer at 300 N, fresh read noise per frame) beside 1024 Hz of the default DAQ channels,
and compares the file on disk with :func:`rigctl.storage.estimate_run_bytes` (what the dry run and
the writer's free-space check use).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.storage import RunReader, RunWriter, estimate_run_bytes
from rigctl.storage.layout import (
    CAMERA,
    FRAME_COMPRESSIONS,
    CameraLayout,
    DaqLayout,
    FrameCompression,
    RunDescription,
)
from sim_devices.contact_image import CameraOptics, ContactImageRenderer

H, W = 480, 640
RATE_HZ = 60.0
SAMPLE_RATE_HZ = 1024.0


def _contact_frames(n: int, fn_N: float = 300.0) -> np.ndarray:
    renderer = ContactImageRenderer(CameraOptics(width_px=W, height_px=H))
    p = np.full(10, 0.1)
    sliding = np.zeros(10, dtype=bool)
    return np.stack([renderer.render(fn_N, p, sliding, 1) for _ in range(n)])


def _record(path: Path, frames: np.ndarray, duration_s: float,
            compression: FrameCompression) -> tuple[DaqLayout, CameraLayout]:
    daq = DaqLayout(sample_rate_hz=SAMPLE_RATE_HZ)
    cam = CameraLayout(height_px=H, width_px=W, frame_rate_hz=RATE_HZ, compression=compression)
    n_samples = int(duration_s * SAMPLE_RATE_HZ)
    rng = np.random.default_rng(1)
    with RunWriter(path, RunDescription(protocol="test"), daq, cam, min_free_bytes=0) as w:
        for a in range(0, n_samples, 64):
            t = np.arange(a, a + 64) / SAMPLE_RATE_HZ
            block = {name: rng.normal(size=64) for name in daq.channels}
            w.append_daq({"t_s": t, **block}, counter=a)
        for i in range(frames.shape[0]):  # one frame per append, as at 60 Hz
            w.append_frames(frames[i], [i / RATE_HZ], [i])
    return daq, cam


@pytest.mark.slow
@pytest.mark.parametrize("compression", ["gzip", "lzf"])
def test_the_size_estimate_is_within_1_5x_of_a_recorded_run(
        tmp_path: Path, compression: FrameCompression) -> None:
    duration_s = 2.0
    frames = _contact_frames(int(duration_s * RATE_HZ))
    path = tmp_path / "run.h5"
    daq, cam = _record(path, frames, duration_s, compression)
    real = path.stat().st_size
    estimate = estimate_run_bytes(duration_s, daq, cam)
    assert real / 1.5 <= estimate <= real * 1.5, (compression, real, estimate)
    with h5py.File(path, "r") as f:
        stored = f[CAMERA]["frames"].id.get_storage_size()
    assert stored < frames.nbytes * 0.8  # contact images do compress with either filter
    # the estimate at most (images that do not compress) bounds the real file
    assert estimate_run_bytes(duration_s, daq, cam, at_most=True) >= real * 0.95


@pytest.mark.parametrize("compression", FRAME_COMPRESSIONS)
def test_frames_read_back_bit_identical(tmp_path: Path, compression: FrameCompression) -> None:
    rng = np.random.default_rng(7)
    frames = np.concatenate([
        _contact_frames(3, fn_N=150.0),
        rng.integers(0, 256, size=(2, H, W), dtype=np.uint8),  # noise: stored as it comes
        np.zeros((1, H, W), np.uint8), np.full((1, H, W), 255, np.uint8),
    ])
    path = tmp_path / "run.h5"
    _record(path, frames, 0.1, compression)
    with RunReader(path) as r:
        back, _t_s, seq = r.frames(0, frames.shape[0])
    np.testing.assert_array_equal(back, frames)
    np.testing.assert_array_equal(seq, np.arange(frames.shape[0]))
    with h5py.File(path, "r") as f:  # plain h5py, no plug-in
        ds = f[CAMERA]["frames"]
        assert ds.compression == (None if compression == "none" else compression)
        assert ds.chunks == (1, H, W) and ds.fletcher32
        np.testing.assert_array_equal(ds[:], frames)


def test_an_unknown_compression_is_refused_before_the_file_exists(tmp_path: Path) -> None:
    cam = CameraLayout(height_px=H, width_px=W, compression="zstd")  # type: ignore[arg-type]
    path = tmp_path / "run.h5"
    with pytest.raises(ValueError, match="frame compression must be one of gzip, lzf, none"):
        RunWriter(path, RunDescription(protocol="test"), DaqLayout(), cam, min_free_bytes=0)
    assert not path.exists()
