"""The Live tab after an hour of data: frame rate, redraw and paint times, and memory over the hour.

The Live tab (:class:`rigctl.gui.live_view.LiveView`, 1400 x 800 px, offscreen) is fed one hour of
simulated data straight into its feeding methods, faster than real time: the model's 1024 Hz
stick-slip stream (``rigctl.gui.soak.simulated_stream``: a TLRE at 300 N and 10 um/s, looped with rig
time running on) in DAQ blocks of 32 samples, and 60 camera frames per rig second, each one a
:class:`~rigctl.runservice.frames.LiveFrame` (a downsampled image and its Isum) as the run service
sends them, but 60 a second instead of a few. The frames are 24 contact images rendered beforehand
by the simulated camera's renderer (640 x 480, loads 0-300 N) and cycled: rendering 216,000 images
would take this benchmark's whole time, and the widget's work does not depend on which image it is.

* **Hour**: each rig second is fed, then redrawn and painted once; the process's resident memory is
  read every rig minute (target: flat once the 60 s history is full).
* **Frame rate**: at the start (after one rig minute) and after the hour, ``--frames`` frames as a
  running window does them: 1024/30 samples and two camera frames fed, redraw, paint (both plot
  views repainted synchronously), events processed; frames per second of wall time (target >= 30)
  and the median and 99th percentile of the redraw and paint times.

``python -m benchmarks.bench_live_view [--hours H] [--frames N] [--json] [--quick]``; ``--quick``
feeds 10 rig minutes. Figures go into docs/performance.md (Live view).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

RATE_HZ = 1024
CAMERA_HZ = 60
BLOCK = 32


@dataclass
class Phase:
    frames: int = 0
    wall_s: float = 0.0
    fps: float = 0.0
    redraw_ms_median: float = 0.0
    redraw_ms_p99: float = 0.0
    paint_ms_median: float = 0.0
    paint_ms_p99: float = 0.0
    cpu_ms_per_frame: float = 0.0
    """Process CPU time per frame (feeding, redraw, paint): what the frame costs, whatever the load."""
    load_average: float = 0.0
    """The machine's 1-minute load average at the end of the phase (2 cores)."""


@dataclass
class Report:
    rig_hours: float = 0.0
    samples: int = 0
    camera_frames: int = 0
    feed_wall_s: float = 0.0
    rss_mb: list[tuple[float, float]] = field(default_factory=list)
    """(rig minutes, resident MB) every rig minute."""
    start: Phase = field(default_factory=Phase)
    end: Phase = field(default_factory=Phase)

    @property
    def rss_growth_mb(self) -> float:
        """Resident memory at the end minus at rig minute 2 (history full, caches warm)."""
        after = [mb for m, mb in self.rss_mb if m >= 2]
        return after[-1] - after[0] if len(after) > 1 else float("nan")


def _frames_pool(n: int = 24) -> list[tuple[np.ndarray, int]]:
    """Downsampled contact images (and their factor) at loads 0-300 N, and their full-size Isum."""
    from rigctl.runservice.frames import downsample
    from sim_devices.contact_image import CameraOptics, ContactImageRenderer

    renderer = ContactImageRenderer(CameraOptics(width_px=640, height_px=480))
    p = np.full(10, 0.1)
    sliding = np.zeros(10, dtype=bool)
    pool = []
    for fn in np.linspace(0.0, 300.0, n):
        full = renderer.render(float(fn), p, sliding, 1)
        pool.append(downsample(full))
    return pool


class _Feeder:
    """The simulated stream and camera frames, rig time running on."""

    def __init__(self) -> None:
        from rigctl.gui.soak import blocks, simulated_stream
        from rigctl.runservice.frames import LiveFrame, intensity_sum

        self._blocks = blocks(simulated_stream(), BLOCK, float(RATE_HZ))
        pool = _frames_pool()
        self._pool = [(img, f, intensity_sum(img) * f * f) for img, f in pool]
        self._frame_cls = LiveFrame
        self.t_s = 0.0
        self._k = 0

    def samples(self, n: int) -> list[dict[str, np.ndarray]]:
        out = []
        got = 0
        while got < n:
            b = next(self._blocks)
            out.append(b)
            got += len(b["t_s"])
        self.t_s = float(out[-1]["t_s"][-1])
        return out

    def frames(self, n: int) -> list[Any]:
        out = []
        for _ in range(n):
            img, factor, isum = self._pool[self._k % len(self._pool)]
            t = self._k / CAMERA_HZ
            self._k += 1
            out.append(self._frame_cls(t, img, factor, np.array([t]), np.array([isum])))
        return out


def _paint(view: Any, app: Any) -> None:
    """Let Qt paint what changed, as the window's event loop does after a redraw (one paint of each
    plot view per frame: the Live tab keeps its axis ranges steady, see live_view.steady_range)."""
    app.processEvents()


def _phase(view: Any, feeder: _Feeder, app: Any, frames: int) -> Phase:
    redraw_ms, paint_ms = [], []
    per_frame = RATE_HZ / 30
    carry = 0.0
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    for _ in range(frames):
        carry += per_frame
        n = int(carry)
        carry -= n
        view.feed_blocks(feeder.samples(n))
        view.feed_frames(feeder.frames(2))
        a = time.perf_counter()
        view.redraw()
        b = time.perf_counter()
        _paint(view, app)
        c = time.perf_counter()
        redraw_ms.append(1e3 * (b - a))
        paint_ms.append(1e3 * (c - b))
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    return Phase(frames, wall, frames / wall, float(np.median(redraw_ms)),
                 float(np.percentile(redraw_ms, 99)), float(np.median(paint_ms)),
                 float(np.percentile(paint_ms, 99)), 1e3 * cpu / frames, os.getloadavg()[0])


def run(hours: float = 1.0, frames: int = 300) -> Report:
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtWidgets import QApplication

    from rigctl.gui.live_view import LiveView
    from rigctl.gui.soak import rss_bytes

    app = QApplication.instance() or QApplication([sys.argv[0]])
    view = LiveView(rate_hz=float(RATE_HZ), camera_rate_hz=float(CAMERA_HZ))
    view._timer.stop()  # redrawn here, not by its own timer
    view.resize(1400, 800)
    view.show()
    app.processEvents()
    feeder = _Feeder()
    report = Report(rig_hours=hours)
    seconds = round(hours * 3600)
    t0 = time.perf_counter()
    for s in range(1, seconds + 1):
        view.feed_blocks(feeder.samples(RATE_HZ))
        view.feed_frames(feeder.frames(CAMERA_HZ))
        view.redraw()
        _paint(view, app)
        if s == 60:
            report.start = _phase(view, feeder, app, frames)
        if s % 60 == 0:
            report.rss_mb.append((s / 60, rss_bytes() / 1e6))
    report.feed_wall_s = time.perf_counter() - t0 - report.start.wall_s
    report.end = _phase(view, feeder, app, frames)
    report.rss_mb.append((seconds / 60 + 0.01, rss_bytes() / 1e6))
    report.samples = view.plot.samples
    report.camera_frames = feeder._k
    view.shutdown()
    return report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_live_view")
    p.add_argument("--hours", type=float, default=1.0)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--json", action="store_true")
    p.add_argument("--quick", action="store_true", help="10 rig minutes")
    args, _ = p.parse_known_args(sys.argv[1:] if argv is None else argv)
    hours = 1 / 6 if args.quick else args.hours
    r = run(hours, args.frames)
    if args.json:
        out = asdict(r)
        out["rss_growth_mb"] = r.rss_growth_mb
        print(json.dumps(out, indent=1))
    else:
        rss = [mb for _, mb in r.rss_mb]
        print(f"live view: {r.rig_hours:g} rig hours, {r.samples} samples, {r.camera_frames} camera "
              f"frames fed in {r.feed_wall_s:.0f} s wall")
        for name, ph in (("start (rig minute 1)", r.start), (f"after {r.rig_hours:g} h", r.end)):
            print(f"  {name}: {ph.fps:.0f} frames/s; redraw {ph.redraw_ms_median:.1f} ms median, "
                  f"{ph.redraw_ms_p99:.1f} ms p99; paint {ph.paint_ms_median:.1f} ms median, "
                  f"{ph.paint_ms_p99:.1f} ms p99; {ph.cpu_ms_per_frame:.1f} ms CPU a frame "
                  f"(load average {ph.load_average:.1f})")
        print(f"  resident memory: {rss[0]:.1f} MB at minute 1, {min(rss):.1f}-{max(rss):.1f} MB over "
              f"the run, {r.rss_growth_mb:+.1f} MB from minute 2 to the end")
    ok = r.end.fps >= 30 and r.rss_growth_mb < 20
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
