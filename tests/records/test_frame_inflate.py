"""The analyses' frame reader (ISA-L inflate of raw chunks) gives exactly what h5py gives.

Frames are contact images rendered by the simulated camera (with read noise) and recorded by the
run writer with each of its compressions; the fast path must be taken where it applies (deflate,
with the writer's Fletcher-32 checksums) and h5py must read whatever it cannot vouch for (another
pipeline, a chunk stored without a filter, a chunk not written, a corrupted chunk).
"""

from __future__ import annotations

import shutil
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.records.contact_frames import iter_frame_chunks
from rigctl.records.frame_inflate import FrameDecoder, fletcher32, pipeline_of, why_not_fast
from rigctl.storage import RunWriter
from rigctl.storage.layout import CAMERA, CameraLayout, DaqLayout, FrameCompression, RunDescription
from rigctl.storage.reader import RunReader
from sim_devices.contact_image import CameraOptics, ContactImageRenderer

H, W = 120, 160
N_FRAMES = 40


def hdf5_fletcher32(data: bytes) -> int:
    """HDF5's H5_checksum_fletcher32 transcribed loop for loop (H5checksum.c), slow but literal."""
    n_words = len(data) // 2
    s1 = s2 = 0
    i = 0
    while n_words:
        t = min(n_words, 360)
        n_words -= t
        for _ in range(t):
            s1 += (data[i] << 8) | data[i + 1]
            i += 2
            s2 += s1
        s1 = (s1 & 0xFFFF) + (s1 >> 16)
        s2 = (s2 & 0xFFFF) + (s2 >> 16)
    if len(data) % 2:
        s1 += data[i] << 8
        s2 += s1
        s1 = (s1 & 0xFFFF) + (s1 >> 16)
        s2 = (s2 & 0xFFFF) + (s2 >> 16)
    s1 = (s1 & 0xFFFF) + (s1 >> 16)
    s2 = (s2 & 0xFFFF) + (s2 >> 16)
    return (s2 << 16) | s1


def recorded(path: Path, compression: FrameCompression) -> Path:
    """A run file with N_FRAMES contact images at loads 0-300 N (fresh read noise per frame)."""
    renderer = ContactImageRenderer(CameraOptics(width_px=W, height_px=H, read_noise_rms=1.2))
    p = np.full(10, 0.1)
    sliding = np.zeros(10, dtype=bool)
    imgs = np.stack([renderer.render(float(fn), p, sliding, 1)
                     for fn in np.linspace(0.0, 300.0, N_FRAMES)])
    t = np.arange(0.0, 1.0, 1e-3)
    cols = {"t_s": t, "x_stage_m": np.zeros_like(t), "fn_N": np.full_like(t, 300.0),
            "ft_N": np.zeros_like(t), "d1_m": np.zeros_like(t), "d2_m": np.zeros_like(t)}
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=H, width_px=W, frame_rate_hz=60.0, compression=compression)
    with RunWriter(path, RunDescription(protocol="sim"), daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        w.append_frames(imgs, np.arange(N_FRAMES) / 60.0, np.arange(N_FRAMES))
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("inflate")
    return {c: recorded(d / f"{c}.h5", c) for c in ("gzip", "lzf", "none")}


def test_fletcher32_is_hdf5s_checksum() -> None:
    rng = np.random.default_rng(3)
    # sums that are multiples of 65535 (HDF5 keeps them as 65535, not 0), odd lengths, zeros
    cases = [b"", b"\x01", b"\xff\xff", b"\xff\xff" * 2, b"\xff" * 721, b"\x00" * 64,
             bytes(range(256)) * 3 + b"\x07"]
    cases += [rng.integers(0, 256, n, dtype=np.uint8).tobytes() for n in (2, 3, 719, 720, 721, 5001)]
    for data in cases:
        assert fletcher32(data) == hdf5_fletcher32(data), len(data)


def test_fletcher32_matches_the_checksums_hdf5_stored(runs: dict[str, Path]) -> None:
    with h5py.File(runs["gzip"], "r") as f:
        ds = f[CAMERA]["frames"]
        for i in range(N_FRAMES):
            mask, raw = ds.id.read_direct_chunk((i, 0, 0))
            assert mask == 0
            assert fletcher32(raw[:-4]) == int.from_bytes(raw[-4:], "little")


@pytest.mark.parametrize("compression", ["gzip", "lzf", "none"])
def test_frames_are_byte_identical_to_h5py(runs: dict[str, Path], compression: str) -> None:
    with h5py.File(runs[compression], "r") as f:
        ds = f[CAMERA]["frames"]
        plain = ds[:]
        dec = FrameDecoder(ds)
        got = np.concatenate([dec.read(a, min(a + 7, N_FRAMES)) for a in range(0, N_FRAMES, 7)])
        assert got.dtype == np.uint8 and got.shape == (N_FRAMES, H, W)
        np.testing.assert_array_equal(got, plain)
        assert np.ptp(plain) > 100  # contact spots on a dark field, not an empty image
        if compression == "gzip":  # the writer's pipeline: deflate then Fletcher-32
            assert pipeline_of(ds) == (h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_FLETCHER32)
            assert (dec.why_not, dec.fast_frames, dec.fallback_frames) == (None, N_FRAMES, 0)
        else:
            assert dec.why_not is not None and "filter pipeline" in dec.why_not
            assert (dec.fast_frames, dec.fallback_frames) == (0, N_FRAMES)


def test_streamed_chunks_read_through_the_decoder(runs: dict[str, Path]) -> None:
    with RunReader(runs["gzip"]) as r:
        frames, t_s, _ = r.frames()
        chunks = list(iter_frame_chunks(r, 3, 37, max_bytes=5 * H * W))
    assert [c.start for c in chunks] == list(range(3, 37, 5))
    np.testing.assert_array_equal(np.concatenate([c.frames for c in chunks]), frames[3:37])
    np.testing.assert_array_equal(np.concatenate([c.t_s for c in chunks]), t_s[3:37])


def test_other_pipelines_and_shapes_are_read_by_h5py(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    data = rng.integers(0, 40, size=(6, 16, 20), dtype=np.uint8)
    with h5py.File(tmp_path / "other.h5", "w") as f:
        shuffled = f.create_dataset("shuffled", data=data, chunks=(1, 16, 20), compression="gzip",
                                    shuffle=True, fletcher32=True)
        two = f.create_dataset("two_per_chunk", data=data, chunks=(2, 16, 20), compression="gzip")
        halves = f.create_dataset("half_frames", data=data, chunks=(1, 8, 20), compression="gzip")
        floats = f.create_dataset("floats", data=data.astype(np.float32), chunks=(1, 16, 20),
                                  compression="gzip")
        for ds, why in ((shuffled, "filter pipeline"), (two, "not one whole frame"),
                        (halves, "not one whole frame"), (floats, "uint8")):
            reason = why_not_fast(ds)
            assert reason is not None and why in reason, reason
            dec = FrameDecoder(ds)
            np.testing.assert_array_equal(dec.read(1, 5), ds[1:5])
            assert (dec.fast_frames, dec.fallback_frames) == (0, 4)


def test_a_chunk_stored_without_deflate_and_an_unwritten_chunk_fall_back(tmp_path: Path) -> None:
    """HDF5 marks a chunk whose optional deflate was skipped in its filter mask (bit 0): the bytes
    are then the pixels and their checksum. Here those pixels happen to begin with a valid zlib
    stream (of another image), so only the mask tells that they are not to be inflated. A chunk
    never written reads as the fill value."""
    rng = np.random.default_rng(1)
    frames = rng.integers(0, 60, size=(4, 16, 20), dtype=np.uint8)
    other = zlib.compress(np.full(16 * 20, 9, dtype=np.uint8).tobytes())
    frames[2].flat[:len(other)] = np.frombuffer(other, dtype=np.uint8)
    with h5py.File(tmp_path / "mask.h5", "w") as f:
        ds = f.create_dataset("frames", shape=(5, 16, 20), chunks=(1, 16, 20), dtype=np.uint8,
                              compression="gzip", compression_opts=1, fletcher32=True)
        ds[0:2] = frames[0:2]
        raw = frames[2].tobytes()
        ds.id.write_direct_chunk((2, 0, 0), raw + fletcher32(raw).to_bytes(4, "little"),
                                 filter_mask=0b01)
        ds[3] = frames[3]  # chunk 4 never written
        assert ds.id.read_direct_chunk((2, 0, 0))[0] == 0b01
        plain = ds[:]
        np.testing.assert_array_equal(plain[:4], frames)
        dec = FrameDecoder(ds)
        np.testing.assert_array_equal(dec.read(0, 5), plain)
        assert (dec.why_not, dec.fast_frames, dec.fallback_frames) == (None, 3, 2)


def test_a_chunk_that_inflates_short_is_read_by_h5py(tmp_path: Path) -> None:
    """A malformed chunk (valid checksum, a zlib stream of fewer bytes than a frame) is handed to
    h5py, which reads the bytes there are (HDF5 leaves the rest of the frame undefined)."""
    with h5py.File(tmp_path / "short.h5", "w") as f:
        ds = f.create_dataset("frames", shape=(3, 16, 20), chunks=(1, 16, 20), dtype=np.uint8,
                              compression="gzip", compression_opts=1, fletcher32=True)
        ds[0] = 3
        ds[2] = 4
        z = zlib.compress(bytes(range(200)))
        ds.id.write_direct_chunk((1, 0, 0), z + fletcher32(z).to_bytes(4, "little"))
        dec = FrameDecoder(ds)
        got = dec.read(0, 3)
        np.testing.assert_array_equal(got[[0, 2]], ds[[0, 2]])
        np.testing.assert_array_equal(got[1].ravel()[:200], np.arange(200))
        assert (dec.fast_frames, dec.fallback_frames) == (2, 1)


@pytest.mark.parametrize("where", ["pixels", "checksum"])
def test_a_corrupted_chunk_fails_as_h5py_fails(runs: dict[str, Path], tmp_path: Path,
                                                where: str) -> None:
    """One flipped byte in a stored frame, in its compressed pixels or in its stored checksum (the
    pixels then still inflate): the checksum no longer matches, h5py reads that frame and reports
    the corruption; the frames around it still read."""
    bad = tmp_path / "bad.h5"
    shutil.copy(runs["gzip"], bad)
    with h5py.File(bad, "r") as f:
        info = f[CAMERA]["frames"].id.get_chunk_info_by_coord((5, 0, 0))
    at = info.byte_offset + (info.size // 2 if where == "pixels" else info.size - 2)
    with bad.open("r+b") as fh:
        fh.seek(at)
        byte = fh.read(1)[0]
        fh.seek(at)
        fh.write(bytes([byte ^ 0x10]))
    with h5py.File(bad, "r") as f:
        ds = f[CAMERA]["frames"]
        with pytest.raises(OSError) as plain_error:
            ds[5:6]
        dec = FrameDecoder(ds)
        with pytest.raises(OSError) as fast_error:
            dec.read(4, 7)
        assert str(fast_error.value) == str(plain_error.value)
        assert dec.fast_frames == 1  # frame 4, then frame 5 fell back to h5py, which raised
        np.testing.assert_array_equal(dec.read(6, 8), ds[6:8])
