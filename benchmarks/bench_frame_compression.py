"""Camera frames in the run file: HDF5 filters and chunk shapes side by side (bytes, write, read).

Frames (640 x 480, uint8) in three sets:

* ``sim``: the simulated camera's renderer (read noise 1.2 grey levels RMS) at loads 0-300 N, every
  frame with fresh read noise, as ``rigctl run`` records them;
* ``noisy``: the same contact images with 4 grey levels RMS of read noise (a warm, cheap sensor, or
  a higher gain);
* ``noise``: uniform random bytes, the worst case (nothing compresses).

Each frame set is written into a fresh file once per filter and chunk shape, exactly as
:class:`rigctl.storage.RunWriter` creates the frames dataset (resizable, Fletcher-32 checksums,
``libver`` v110), in appends of ``--batch`` frames (the acquisition's writer thread hands over what
its queue holds: 1 frame at a time at 60 Hz, up to 32 when it catches up); then read back the way
the analyses stream frames (:func:`rigctl.records.contact_frames.chunk_frames`: ~100 frames per
read). Reported per case: bytes per frame on disk (``Dataset.id.get_storage_size()``), the ratio
to raw pixels, write frames/s (wall) and the CPU milliseconds one frame's write costs (the figure
that does not depend on the machine's load: 60 Hz needs 1000 / 60 = 16.7 ms or less of one core),
read frames/s, and whether plain h5py (no plug-in) can read the file.

Filters: none; lzf; gzip (deflate) 1/4/6, each with and without the shuffle filter (for uint8 a
byte shuffle is an identity: the figures show its cost); and, when ``hdf5plugin`` is installed,
Blosc (zstd and lz4, bit-shuffled) and plain Zstandard. Chunks: 1 frame per chunk (the writer's)
or ``--frames-per-chunk`` frames per chunk.

``python -m benchmarks.bench_frame_compression [--frames N] [--batch B] [--frames-per-chunk K]
[--quick] [--json]``. Figures go into docs/performance.md (Camera frames) and docs/run-file.md.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from rigctl.records.contact_frames import DEFAULT_CHUNK_BYTES, chunk_frames
from rigctl.storage.layout import LIBVER
from sim_devices.contact_image import CameraOptics, ContactImageRenderer

H, W = 480, 640
N_ELEMENTS = 10

Frames = NDArray[np.uint8]


@dataclass
class Case:
    frames: str
    filter: str
    frames_per_chunk: int
    bytes_per_frame: float
    ratio: float
    write_fps: float
    write_cpu_ms: float
    read_fps: float
    plain_h5py: bool


@dataclass
class Report:
    n_frames: int = 0
    batch: int = 1
    read_frames: int = 0
    hdf5plugin: str = ""
    load_average: float = 0.0
    cases: list[Case] = field(default_factory=list)


def contact_frames(n: int, read_noise_rms: float, seed: int = 2022) -> Frames:
    """``n`` frames of the simulated camera at loads 0-300 N (uniform load shares, sticking)."""
    renderer = ContactImageRenderer(
        CameraOptics(width_px=W, height_px=H, read_noise_rms=read_noise_rms, seed=seed)
    )
    p = np.full(N_ELEMENTS, 1.0 / N_ELEMENTS)
    sliding = np.zeros(N_ELEMENTS, dtype=bool)
    loads_N = np.linspace(0.0, 300.0, n)
    return np.stack([renderer.render(float(fn), p, sliding, 1) for fn in loads_N])


def noise_frames(n: int, seed: int = 2022) -> Frames:
    """Uniform random bytes: nothing can compress them."""
    return np.random.default_rng(seed).integers(0, 256, size=(n, H, W), dtype=np.uint8)


def filters() -> tuple[dict[str, dict[str, Any]], str]:
    """Name -> ``create_dataset`` keywords of every filter tried, and the hdf5plugin version."""
    out: dict[str, dict[str, Any]] = {"none": {}, "lzf": {"compression": "lzf"}}
    for level in (1, 4, 6):
        out[f"gzip {level}"] = {"compression": "gzip", "compression_opts": level}
        out[f"gzip {level} + shuffle"] = {
            "compression": "gzip", "compression_opts": level, "shuffle": True
        }
    try:
        import hdf5plugin
    except ImportError:
        return out, ""
    bit = hdf5plugin.Blosc.BITSHUFFLE
    out["blosc zstd 5 bitshuffle"] = dict(hdf5plugin.Blosc(cname="zstd", clevel=5, shuffle=bit))
    out["blosc lz4 5 bitshuffle"] = dict(hdf5plugin.Blosc(cname="lz4", clevel=5, shuffle=bit))
    out["zstd 3"] = dict(hdf5plugin.Zstd(clevel=3))
    return out, str(hdf5plugin.version)


def write_frames(path: Path, frames: Frames, kwargs: Mapping[str, Any], per_chunk: int,
                 batch: int) -> tuple[float, float]:
    """Wall and CPU seconds to write ``frames`` as the run writer does (resize + write per batch,
    flush, close)."""
    t0, cpu0 = time.perf_counter(), time.process_time()
    with h5py.File(path, "w", libver=LIBVER) as f:
        ds = f.create_dataset("frames", shape=(0, H, W), maxshape=(None, H, W),
                              chunks=(per_chunk, H, W), dtype=np.uint8, fletcher32=True,
                              **kwargs)
        f.swmr_mode = True
        for a in range(0, frames.shape[0], batch):
            block = frames[a:a + batch]
            ds.resize(a + block.shape[0], axis=0)
            ds[a:] = block
        f.flush()
    return time.perf_counter() - t0, time.process_time() - cpu0


def read_frames(path: Path, step: int, check: Frames) -> tuple[float, int]:
    """Seconds to read every frame in reads of ``step`` frames; the bytes the dataset stores."""
    t0 = time.perf_counter()
    with h5py.File(path, "r", swmr=True) as f:
        ds = f["frames"]
        n = ds.shape[0]
        for a in range(0, n, step):
            chunk = ds[a:a + step]
            if not np.array_equal(chunk, check[a:a + step]):
                raise AssertionError(f"{path}: frames {a}.. read back differ")
        seconds = time.perf_counter() - t0
        stored = int(ds.id.get_storage_size())
    return seconds, stored


def readable_by_plain_h5py(kwargs: Mapping[str, Any]) -> bool:
    """True when HDF5 has the filter built in (no plug-in library needed to read)."""
    return "compression" not in kwargs or kwargs["compression"] in ("gzip", "lzf")


def run(n: int, batch: int, per_chunk: int, quick: bool = False,
        progress: Callable[[str], None] | None = None) -> Report:
    step = min(chunk_frames(H, W, DEFAULT_CHUNK_BYTES), n)
    sets = {"sim": contact_frames(n, 1.2), "noisy": contact_frames(n, 4.0),
            "noise": noise_frames(n)}
    table, plugin = filters()
    if quick:
        table = {k: v for k, v in table.items() if k in ("none", "lzf", "gzip 1", "gzip 1 + shuffle")}
    rep = Report(n_frames=n, batch=batch, read_frames=step, hdf5plugin=plugin,
                 load_average=os.getloadavg()[0])
    chunkings = (1,) if per_chunk == 1 else (1, per_chunk)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.h5"
        for set_name, frames in sets.items():
            for name, kwargs in table.items():
                for k in chunkings:
                    write_s, write_cpu_s = write_frames(path, frames, kwargs, k, batch)
                    read_s, stored = read_frames(path, step, frames)
                    case = Case(set_name, name, k, stored / n, frames.nbytes / stored, n / write_s,
                                1e3 * write_cpu_s / n, n / read_s, readable_by_plain_h5py(kwargs))
                    rep.cases.append(case)
                    if progress is not None:
                        progress(_row(case))
                    path.unlink()
    rep.load_average = max(rep.load_average, os.getloadavg()[0])
    return rep


def _row(c: Case) -> str:
    return (f"{c.frames:<6} {c.filter:<24} {c.frames_per_chunk:>5} {c.bytes_per_frame / 1e3:>9.1f}"
            f" {c.ratio:>6.2f} {c.write_fps:>8.0f} {c.write_cpu_ms:>7.1f} {c.read_fps:>8.0f}  "
            + ("yes" if c.plain_h5py else "needs hdf5plugin"))


HEADER = (f"{'frames':<6} {'filter':<24} {'f/chk':>5} {'kB/frame':>9} {'ratio':>6} "
          f"{'write/s':>8} {'cpu ms':>7} {'read/s':>8}  plain h5py")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_frame_compression")
    p.add_argument("--frames", type=int, default=120, help="frames per set (default 120)")
    p.add_argument("--batch", type=int, default=1, help="frames per append (default 1, as at 60 Hz)")
    p.add_argument("--frames-per-chunk", type=int, default=8,
                   help="the multi-frame chunk shape tried beside 1 frame per chunk (default 8)")
    p.add_argument("--quick", action="store_true", help="24 frames, 4 filters (a smoke run)")
    p.add_argument("--json", action="store_true")
    args, _ = p.parse_known_args(argv)
    if args.frames < 1 or args.batch < 1 or args.frames_per_chunk < 1:
        p.error("--frames, --batch and --frames-per-chunk must be >= 1")
    n = 24 if args.quick else args.frames
    if not args.json:
        print(f"{W} x {H} px frames, {n} per set, appended {args.batch} at a time, read "
              f"{min(chunk_frames(H, W, DEFAULT_CHUNK_BYTES), n)} at a time; Fletcher-32 on")
        print(HEADER, flush=True)
    rep = run(n, args.batch, args.frames_per_chunk, args.quick,
              None if args.json else lambda line: print(line, flush=True))
    if args.json:
        print(json.dumps(asdict(rep), indent=1))
        return 0
    print(f"hdf5plugin {rep.hdf5plugin or 'not installed (its filters skipped)'}; "
          f"load average {rep.load_average:.1f} (2 cores)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
