"""Sustained acquisition to HDF5: the rig's rates and 10x those rates, side by side in one run.

Each case records for ``--minutes`` (default 10) of wall time into a real run file through the real
acquisition (:class:`rigctl.acquisition.Acquisition`: DAQ, camera and writer threads) and reports,
every few seconds: samples, dropped samples (DAQ counter gaps + writer-queue refusals, target 0),
frames and dropped frames, the writer lag (host time from a block's arrival to its hand-over to
the run file), the writer queue depth and the process's resident memory (target flat).

* ``rig-1x``: the simulated rig behind the real drivers on their wires (``sim-wire``: Modbus TCP
  stages, the CAN DAQ, pty probes) at 1024 Hz x 6 channels and a 60 Hz 640x480 camera, the rig
  loaded to 300 N and sliding at 1.3 um/s, frames rendered live.
* ``rig-10x``: the in-process simulated rig at speed 10 (10,240 samples/s, 600 frames/s of
  640x480). Rendering 600 contact images a second would take more than this machine's two cores,
  so the camera replays 120 frames rendered beforehand by the same renderer from a loaded, sliding
  contact; everything downstream of the camera (timestamps, queue, HDF5) is the real work. Frames
  are stored uncompressed here (``storage.frame_compression = "none"``): lzf tops out near 400-500
  frames/s of these noisy 640x480 images on one core (hardware.md: lzf keeps up with 60 Hz).

``python -m benchmarks.bench_acquisition [--minutes M] [--cases rig-1x,rig-10x] [--json]
[--keep DIR]``. Figures go into docs/performance.md (Acquisition).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rigctl.acquisition import Acquisition, RigDevices
from rigctl.config import adapters
from rigctl.config.loader import default_config
from rigctl.storage import RunWriter
from rigctl.storage.layout import RunDescription
from sim_devices.backends import SimRig, build_sim_rig

LOAD_Z_M = 0.020057
"""Normal stage position giving about 300 N on the default simulated contact."""
DRIVE_M_S = 1.3e-6
SAMPLE_EVERY_S = 5.0
SEGMENT_S = 120.0
"""Length of one run file in the 10x case (see run_case)."""


def rss_mib() -> float:
    """Resident memory of this process [MiB] (Linux /proc)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _pre_rendered(sim: SimRig, n: int = 120) -> list[np.ndarray]:
    """n contact images of a loaded, sliding contact, rendered by the camera's own renderer."""
    cam = sim.devices.camera
    rig = sim.rig
    t_end = rig.t_s
    span = min(t_end, 4.0)
    return [cam.frame_at(t_end - span + span * k / n) for k in range(n)]  # type: ignore[attr-defined]


def _load_and_slide(sim: SimRig, speed: float) -> None:
    normal, tangential = sim.devices.normal_stage, sim.devices.tangential_stage
    normal.enable()
    tangential.enable()
    normal.move_absolute(LOAD_Z_M, 1e-3 * min(speed, 1.0))
    x0 = tangential.position_m()
    tangential.move_absolute(x0 + 0.02, DRIVE_M_S)  # far: slides for the whole benchmark


def run_case(name: str, minutes: float, folder: Path, progress: Callable[[str], None]) -> dict[str, Any]:
    speed = 1.0 if name == "rig-1x" else 10.0
    backend = "sim-wire" if name == "rig-1x" else "sim"
    config = default_config()
    if name != "rig-1x":
        config = dataclasses.replace(
            config, storage=dataclasses.replace(config.storage, frame_compression="none"))
    sim = build_sim_rig(backend, settings=adapters.sim_settings(config), speed=speed)
    try:
        _load_and_slide(sim, speed)
        if name != "rig-1x":
            time.sleep(0.5)  # some loaded, sliding rig time to render from
            frames = _pre_rendered(sim)
            counter = [0]

            def replay(t_s: float) -> np.ndarray:
                counter[0] += 1
                return frames[counter[0] % len(frames)]

            sim.devices.camera._image_at = replay  # type: ignore[attr-defined]
        devices = RigDevices.from_device_set(sim.devices)
        # 10x frames are 184 MB/s uncompressed: 110 GB in 10 minutes, more than a lab disk keeps
        # free. The recording is split into segments of SEGMENT_S, each a complete run file that
        # is deleted once closed (the preflight would refuse one 10-minute file, rightly).
        segment_s = minutes * 60.0 if name == "rig-1x" else min(SEGMENT_S, minutes * 60.0)
        rss0 = rss_mib()
        series: list[dict[str, float]] = []
        totals = {"samples": 0, "dropped": 0, "frames": 0, "frames_dropped": 0, "lag_max": 0.0,
                  "bytes": 0}
        errors: list[str] = []
        t0 = time.monotonic()
        end = t0 + minutes * 60.0
        next_sample = t0 + SAMPLE_EVERY_S
        k = 0
        while time.monotonic() < end - 1.0:
            path = folder / f"{name}-{k}.h5"
            seg_end = min(end, time.monotonic() + segment_s)
            writer = RunWriter(path, RunDescription(protocol=f"bench {name}"),
                               adapters.daq_layout(config), adapters.camera_layout(config),
                               flush_interval_s=config.storage.flush_interval_s, overwrite=True,
                               expected_duration_s=(seg_end - time.monotonic()) * speed)
            acq = Acquisition(devices, writer)
            acq.start()
            base = dict(totals)
            while time.monotonic() < seg_end:
                time.sleep(min(0.2, max(0.0, seg_end - time.monotonic())))
                acq.check()
                if time.monotonic() >= next_sample:
                    next_sample += SAMPLE_EVERY_S
                    st = acq.stats
                    row = {
                        "t_s": time.monotonic() - t0, "samples": base["samples"] + st.daq_samples,
                        "dropped": base["dropped"] + st.daq_dropped + st.queue_dropped_samples,
                        "frames": base["frames"] + st.frames,
                        "frames_dropped": base["frames_dropped"] + st.frames_dropped
                        + st.queue_dropped_frames,
                        "lag_s": st.writer_lag_last_s, "queue": acq.queue_depth, "rss_mib": rss_mib(),
                    }
                    series.append(row)
                    progress(f"{name}: {row['t_s']:6.0f} s  samples {row['samples']:>10,}  dropped "
                             f"{row['dropped']}  frames {row['frames']:>8,} (dropped "
                             f"{row['frames_dropped']})  lag {row['lag_s']:.3f} s  queue "
                             f"{row['queue']}  RSS {row['rss_mib']:.0f} MiB")
            st = acq.stop()
            totals["samples"] += st.daq_samples
            totals["dropped"] += st.daq_dropped + st.queue_dropped_samples
            totals["frames"] += st.frames
            totals["frames_dropped"] += st.frames_dropped + st.queue_dropped_frames
            totals["lag_max"] = max(totals["lag_max"], st.writer_lag_max_s)
            totals["bytes"] += path.stat().st_size
            errors += st.errors
            path.unlink()
            k += 1
        wall = time.monotonic() - t0
    finally:
        sim.close()
    half = [r for r in series if r["t_s"] >= wall / 2] or series
    slope = (float(np.polyfit([r["t_s"] for r in half], [r["rss_mib"] for r in half], 1)[0]) * 60.0
             if len(half) >= 3 else float("nan"))
    return {
        "case": name, "wall_s": wall, "speed": speed,
        "segments": k, "samples": totals["samples"], "samples_per_s": totals["samples"] / wall,
        "dropped_samples": totals["dropped"],
        "frames": totals["frames"], "frames_per_s": totals["frames"] / wall,
        "dropped_frames": totals["frames_dropped"],
        "writer_lag_max_s": totals["lag_max"],
        "writer_lag_p99_s": float(np.percentile([r["lag_s"] for r in series], 99)) if series else 0.0,
        "queue_max": max((r["queue"] for r in series), default=0),
        "rss_start_mib": rss0, "rss_end_mib": series[-1]["rss_mib"] if series else rss_mib(),
        "rss_slope_second_half_mib_per_min": slope,
        "file_mib": totals["bytes"] / 2**20,
        "file_mib_per_min": totals["bytes"] / 2**20 / (wall / 60.0),
        "errors": errors,
    }


def format_table(results: list[dict[str, Any]]) -> str:
    head = ("| case | minutes | samples/s | dropped samples | frames/s | dropped frames | writer lag "
            "max / p99 | RSS start -> end (slope, 2nd half) | file |")
    lines = [head, "|" + " --- |" * 9]
    for r in results:
        lines.append(
            f"| {r['case']} | {r['wall_s'] / 60:.1f} | {r['samples_per_s']:,.0f} | {r['dropped_samples']} | "
            f"{r['frames_per_s']:.1f} | {r['dropped_frames']} | {r['writer_lag_max_s']:.3f} / "
            f"{r['writer_lag_p99_s']:.3f} s | {r['rss_start_mib']:.0f} -> {r['rss_end_mib']:.0f} MiB "
            f"({r['rss_slope_second_half_mib_per_min']:+.2f} MiB/min) | {r['file_mib_per_min']:.0f} MiB/min |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench_acquisition", description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--cases", default="rig-1x,rig-10x")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    ap.add_argument("--keep", type=Path, default=None, help="keep the run files in this folder")
    ap.add_argument("--quick", action="store_true", help="0.2 minutes per case (a smoke run)")
    args, _ = ap.parse_known_args(sys.argv[1:] if argv is None else argv)
    minutes = 0.2 if args.quick else args.minutes
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    for c in cases:
        if c not in ("rig-1x", "rig-10x"):
            print(f"unknown case {c!r} (rig-1x, rig-10x)", file=sys.stderr)
            return 2
    results = []
    with tempfile.TemporaryDirectory(prefix="bench_acq_") as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for c in cases:
            results.append(run_case(c, minutes, folder, lambda m: print(m, file=sys.stderr, flush=True)))
    if args.json:
        clean = [{k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                  for k, v in r.items()} for r in results]
        print(json.dumps(clean, indent=2))
    else:
        print(format_table(results))
    bad = [r["case"] for r in results if r["dropped_samples"] or r["errors"]]
    if bad:
        print(f"dropped samples or errors in: {', '.join(bad)}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
