"""Contact images: the intensity pass against a plain h5py read of the same frames, and its memory.

A synthetic run file (``--frames`` frames of 640 x 480 at 60 Hz, stored by the run writer with the
camera's compression, ``--compression``, by default the layout's) is written once: 24 contact
images rendered by the simulated camera's renderer at loads 0-300 N, cycled, each with fresh read
noise so that the compression sees what a real recording gives. Then, in one run, side by side:

* **read**: ``h5py`` reads every frame of the file, chunk by chunk (the same chunk size), and does
  nothing with them: what reading costs (decompression included).
* **decoder read**: the analyses' reader, :class:`rigctl.records.frame_inflate.FrameDecoder`
  (ISA-L's inflate, h5py for what it cannot handle), reads the same frames and does nothing with
  them; how many frames it inflated itself and how many h5py read.
* **intensity**: :func:`rigctl.records.contact_intensity.stream_intensity` over the same frames
  (Isum, Ic and I(x, t) in 100 bins, Sec. 2.2 and 3.2): frames/s and its ratio to both reads.
* **compute**: the intensity pass's arithmetic alone on one chunk already in memory (frames/s).
* **memory**: the peak of ``tracemalloc`` during the intensity pass for several chunk sizes, next to
  the file's pixels and what the pass keeps per frame.

Reads and passes alternate ``--repeat`` times (best of each), so all see the same load and page
cache. ``--profile`` prints cProfile's top entries of one intensity pass.

``python -m benchmarks.bench_contact [--frames N] [--compression gzip|lzf|none] [--repeat R]
[--profile] [--json] [--keep FILE] [--quick]``; ``--quick``: 300 frames, once.
Figures go into docs/performance.md (Contact images).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import sys
import tempfile
import time
import tracemalloc
from dataclasses import asdict, dataclass, field
from pathlib import Path

import h5py
import numpy as np

from rigctl.records.contact_frames import DEFAULT_CHUNK_BYTES, chunk_frames
from rigctl.records.contact_intensity import (
    ContactRegion,
    find_contact_region,
    stream_intensity,
)
from rigctl.records.frame_inflate import FrameDecoder
from rigctl.storage import RunWriter
from rigctl.storage.layout import (
    CAMERA,
    FRAME_COMPRESSIONS,
    CameraLayout,
    DaqLayout,
    FrameCompression,
    RunDescription,
)
from rigctl.storage.reader import RunReader

H, W = 480, 640
RATE_HZ = 60.0
MEMORY_CHUNKS_MB = (2, 8, 32, 128)


@dataclass
class Report:
    frames: int = 0
    compression: str = ""
    height_px: int = H
    width_px: int = W
    file_mb: float = 0.0
    pixels_mb: float = 0.0
    chunk_frames: int = 0
    write_s: float = 0.0
    read_fps: float = 0.0
    """Plain h5py read."""
    decoder_fps: float = 0.0
    """The analyses' reader (FrameDecoder) alone."""
    decoder_fast_frames: int = 0
    """Frames of one decoder read that ISA-L inflated (the rest h5py read)."""
    decoder_over_read: float = 0.0
    """Time of the decoder read / time of the plain read."""
    intensity_fps: float = 0.0
    intensity_over_read: float = 0.0
    """Time of the intensity pass / time of the plain read (1 = costs what h5py's read costs)."""
    intensity_over_decoder: float = 0.0
    """Time of the intensity pass / time of the decoder read (the analysis beyond reading)."""
    compute_fps: float = 0.0
    region_s: float = 0.0
    """find_contact_region (48 frames spread over the run)."""
    peak_mb_by_chunk_mb: dict[str, float] = field(default_factory=dict)
    kept_mb: float = 0.0
    """What the pass keeps per frame, for all frames (t, Isum, Ic, 100 bins, flags)."""
    load_average: float = 0.0


def write_file(path: Path, n: int, compression: FrameCompression, seed: int = 0) -> float:
    """The synthetic run file; returns the seconds it took."""
    from sim_devices.contact_image import CameraOptics, ContactImageRenderer

    t0 = time.perf_counter()
    renderer = ContactImageRenderer(CameraOptics(width_px=W, height_px=H, read_noise_rms=0.0))
    p = np.full(10, 0.1)
    sliding = np.zeros(10, dtype=bool)
    pool = [renderer.render(float(fn), p, sliding, 1).astype(np.float32)
            for fn in np.linspace(0.0, 300.0, 24)]
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, n / RATE_HZ + 1.0, 1.0 / 1024)
    cols = {"t_s": t, "x_stage_m": np.zeros_like(t), "fn_N": np.full_like(t, 300.0),
            "ft_N": np.zeros_like(t), "d1_m": np.zeros_like(t), "d2_m": np.zeros_like(t)}
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=H, width_px=W, frame_rate_hz=RATE_HZ, compression=compression)
    noise = rng.normal(0.0, 1.2, size=(8, H, W)).astype(np.float32)
    with RunWriter(path, RunDescription(protocol="bench"), daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        for a in range(0, n, 32):
            k = min(32, n - a)
            imgs = np.stack([np.clip(np.rint(pool[(a + i) % 24] + noise[(a + i) % 8]
                                             + rng.normal(0.0, 0.3)), 0, 255)
                             for i in range(k)]).astype(np.uint8)
            w.append_frames(imgs, np.arange(a, a + k) / RATE_HZ, np.arange(a, a + k))
    return time.perf_counter() - t0


def plain_read(path: Path, n: int, step: int) -> float:
    """Seconds to read every frame with h5py, ``step`` frames at a time, doing nothing else."""
    t0 = time.perf_counter()
    with h5py.File(path, "r") as f:
        ds = f[CAMERA]["frames"]
        for a in range(0, n, step):
            frames = ds[a:min(a + step, n)]
            del frames
    return time.perf_counter() - t0


def decoder_read(path: Path, n: int, step: int) -> tuple[float, int]:
    """Seconds to read every frame with the analyses' FrameDecoder, ``step`` frames at a time, and
    the frames it inflated itself."""
    t0 = time.perf_counter()
    with h5py.File(path, "r") as f:
        dec = FrameDecoder(f[CAMERA]["frames"])
        for a in range(0, n, step):
            frames = dec.read(a, min(a + step, n))
            del frames
    return time.perf_counter() - t0, dec.fast_frames


def intensity_pass(path: Path, region: ContactRegion, max_bytes: int = DEFAULT_CHUNK_BYTES) -> float:
    t0 = time.perf_counter()
    with RunReader(path) as r:
        stream_intensity(r, region, max_bytes=max_bytes)
    return time.perf_counter() - t0


def compute_only(path: Path, region: ContactRegion, step: int, repeat: int = 5) -> float:
    """Frames/s of the intensity arithmetic on one chunk in memory (a one-chunk fake reader)."""
    with RunReader(path) as r:
        imgs, t_s, seq = r.frames(0, step)

    class _Mem:
        path = Path("memory")
        n_frames = int(imgs.shape[0])

        def frames(self, a: int, b: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return imgs[a:b], t_s[a:b], seq[a:b]

    mem = _Mem()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        stream_intensity(mem, region)  # type: ignore[arg-type]
        best = min(best, time.perf_counter() - t0)
    return imgs.shape[0] / best


def peak_memory_mb(path: Path, region: ContactRegion, chunk_mb: int) -> float:
    tracemalloc.start()
    try:
        intensity_pass(path, region, chunk_mb * 2**20)
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def profile(path: Path, region: ContactRegion, top: int = 14) -> str:
    pr = cProfile.Profile()
    pr.enable()
    intensity_pass(path, region)
    pr.disable()
    s = io.StringIO()
    pstats.Stats(pr, stream=s).sort_stats("tottime").print_stats(top)
    return s.getvalue()


def run(n: int, repeat: int, compression: FrameCompression, keep: Path | None = None,
        show_profile: bool = False) -> Report:
    rep = Report(frames=n, compression=compression, load_average=os.getloadavg()[0])
    with tempfile.TemporaryDirectory() as tmp:
        path = keep or Path(tmp) / "bench_contact.h5"
        if not path.exists():
            rep.write_s = write_file(path, n, compression)
        with h5py.File(path, "r") as f:
            rep.compression = str(f[CAMERA]["frames"].compression or "none")
        rep.file_mb = path.stat().st_size / 2**20
        rep.pixels_mb = n * H * W / 2**20
        step = chunk_frames(H, W, DEFAULT_CHUNK_BYTES)
        rep.chunk_frames = step
        t0 = time.perf_counter()
        with RunReader(path) as r:
            region = find_contact_region(r)
        rep.region_s = time.perf_counter() - t0
        decoder_read(path, min(n, 2), step)  # numba's checksum compiled or loaded from its cache
        read_s, dec_s, pass_s = [], [], []
        for _ in range(repeat):
            read_s.append(plain_read(path, n, step))
            dt, rep.decoder_fast_frames = decoder_read(path, n, step)
            dec_s.append(dt)
            pass_s.append(intensity_pass(path, region))
        rep.read_fps = n / min(read_s)
        rep.decoder_fps = n / min(dec_s)
        rep.decoder_over_read = min(dec_s) / min(read_s)
        rep.intensity_fps = n / min(pass_s)
        rep.intensity_over_read = min(pass_s) / min(read_s)
        rep.intensity_over_decoder = min(pass_s) / min(dec_s)
        rep.compute_fps = compute_only(path, region, step)
        for mb in MEMORY_CHUNKS_MB:
            rep.peak_mb_by_chunk_mb[str(mb)] = round(peak_memory_mb(path, region, mb), 1)
        rep.kept_mb = n * (8 * 3 + 4 * 100 + 4 + 1) / 2**20
        if show_profile:
            print(profile(path, region), file=sys.stderr)
    rep.load_average = max(rep.load_average, os.getloadavg()[0])
    return rep


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_contact")
    p.add_argument("--frames", type=int, default=3000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--compression", choices=FRAME_COMPRESSIONS,
                   default=CameraLayout(1, 1).compression)
    p.add_argument("--profile", action="store_true", help="cProfile of one intensity pass")
    p.add_argument("--json", action="store_true")
    p.add_argument("--keep", type=Path, help="write (or reuse) the run file here")
    p.add_argument("--quick", action="store_true", help="300 frames, one repeat (a smoke run)")
    args, _ = p.parse_known_args(sys.argv[1:] if argv is None else argv)  # run_all's flags too
    n, repeat = (300, 1) if args.quick else (args.frames, args.repeat)
    rep = run(n, repeat, args.compression, args.keep, args.profile)
    if args.json:
        print(json.dumps(asdict(rep), indent=1))
        return 0
    print(f"{rep.frames} frames of {W} x {H} px: {rep.pixels_mb:.0f} MB of pixels, "
          f"{rep.file_mb:.0f} MB on disk ({rep.compression}); chunks of {rep.chunk_frames} frames")
    print(f"plain h5py read   {rep.read_fps:8.0f} frames/s")
    print(f"decoder read      {rep.decoder_fps:8.0f} frames/s  "
          f"({rep.decoder_over_read:.2f} x the h5py read time; "
          f"{rep.decoder_fast_frames}/{rep.frames} frames inflated by ISA-L)")
    print(f"intensity pass    {rep.intensity_fps:8.0f} frames/s  "
          f"({rep.intensity_over_read:.2f} x the h5py read time, "
          f"{rep.intensity_over_decoder:.2f} x the decoder read time)")
    print(f"arithmetic only   {rep.compute_fps:8.0f} frames/s (one chunk in memory)")
    print(f"contact region    {rep.region_s:8.2f} s")
    print("peak memory of the pass by chunk size: " + ", ".join(
        f"{k} MB -> {v:.0f} MB" for k, v in rep.peak_mb_by_chunk_mb.items())
          + f" (kept per frame, all frames: {rep.kept_mb:.1f} MB)")
    print(f"load average {rep.load_average:.1f} (2 cores)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
