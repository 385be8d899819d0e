"""Streaming frames from a run file: chunks cover every frame once, in order, and memory stays bounded."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.records.contact_frames import chunk_frames, iter_frame_chunks, read_frame
from rigctl.records.contact_intensity import ContactRegion, stream_intensity
from rigctl.storage import RunWriter
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from rigctl.storage.reader import RunReader

H, W = 96, 128


def frames_file(path: Path, n: int, seed: int = 0) -> Path:
    """A run file with ``n`` noisy frames at 60 Hz (each frame's first pixel = its index % 256)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, n / 60.0 + 1.0, 1e-3)
    cols = {"t_s": t, "x_stage_m": np.zeros_like(t), "fn_N": np.full_like(t, 300.0),
            "ft_N": np.zeros_like(t), "d1_m": np.zeros_like(t), "d2_m": np.zeros_like(t)}
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=H, width_px=W, frame_rate_hz=60.0)
    with RunWriter(path, RunDescription(protocol="sim"), daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        for a in range(0, n, 50):
            k = min(50, n - a)
            img = rng.integers(0, 40, size=(k, H, W), dtype=np.uint8)
            img[:, 0, 0] = (np.arange(a, a + k) % 256).astype(np.uint8)
            w.append_frames(img, np.arange(a, a + k) / 60.0, np.arange(a, a + k))
    return path


@pytest.fixture(scope="module")
def many(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return frames_file(tmp_path_factory.mktemp("frames") / "many.h5", 1200)


def test_chunk_size_follows_the_byte_budget() -> None:
    assert chunk_frames(480, 640, 32 * 2**20) == 109
    assert chunk_frames(480, 640, 1000) == 1  # always at least one frame
    with pytest.raises(ValueError, match="positive"):
        chunk_frames(0, 640)


def test_chunks_cover_every_frame_once_in_order(many: Path) -> None:
    budget = 10 * H * W + 5  # 10 frames per chunk
    seen = []
    with RunReader(many) as r:
        for ch in iter_frame_chunks(r, 7, 1003, max_bytes=budget):
            assert ch.frames.nbytes <= budget
            assert ch.n == ch.t_s.shape[0]
            seen.extend(ch.frames[:, 0, 0].tolist())
            np.testing.assert_allclose(ch.t_s, np.arange(ch.start, ch.stop) / 60.0)
    assert seen == [i % 256 for i in range(7, 1003)]
    frame, t = read_frame(many, 300)
    assert frame[0, 0] == 300 % 256 and t == pytest.approx(5.0)


def test_bad_ranges_are_named(many: Path, tmp_path: Path) -> None:
    with RunReader(many) as r, pytest.raises(DataError, match="outside the run's 0:1200"):
        list(iter_frame_chunks(r, 0, 1201))
    with pytest.raises(DataError, match="frame 5000 is outside"):
        read_frame(many, 5000)


def _peak_bytes(path: Path, max_bytes: int) -> int:
    with RunReader(path) as r:
        region = ContactRegion(10, 110, 20.0)
        tracemalloc.start()
        try:
            tracemalloc.reset_peak()
            ci = stream_intensity(r, region, max_bytes=max_bytes)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    assert ci.n_frames == 1200
    return peak


def test_streaming_peak_memory_is_bounded_by_the_chunk_not_the_run(many: Path) -> None:
    total = 1200 * H * W  # 14.7 MB of pixels
    kept = 1200 * (100 * 4 + 3 * 8 + 6)  # kept per frame: profile, t, Isum, Ic, frame checks
    small = 8 * H * W
    big = 64 * H * W
    peak_small = _peak_bytes(many, small)
    peak_big = _peak_bytes(many, big)
    # a chunk of pixels plus its column sums, the per-frame results and small change
    assert peak_small < kept + 6 * small + 256 * 1024, peak_small
    assert peak_small < total / 8
    # memory follows the chunk size, one chunk alive at a time: 8x larger chunks cost one chunk's
    # difference more (two chunks alive, the reader's and the caller's, would cost twice that)
    assert peak_small + 0.8 * (big - small) < peak_big < peak_small + 1.5 * (big - small)
