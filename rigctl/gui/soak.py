"""Soak the live view: feed it simulated 1024 Hz data and redraw it many times, counting what leaks.

``python -m rigctl.gui.soak --redraws 2000 --json`` builds a :class:`~rigctl.gui.live_plot.LivePlot`
(offscreen or on a screen), feeds it the stick-slip stream of the model (``rigctl.model.Simulator``,
a TLRE at 300 N and 10 um/s, looped with continuous rig time) in DAQ-sized blocks, ``1024/fps``
samples per redraw, and after each redraw paints the window synchronously. It records
``sys.getrefcount`` of None, True and False, the redraw and paint times and the resident memory,
and prints them. A binding that drops references on Qt calls makes the process abort here
(``none_dealloc``) or shows as a falling count; ``tests/gui/test_refcount_soak.py`` runs it in a child
process and fails on either. (The Live tab's frame rate and memory after an hour of data are
measured by ``benchmarks/bench_live_view.py``.)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field

import numpy as np

RATE_HZ = 1024.0
STREAM_S = 60.0
BLOCK_SAMPLES = 32


def simulated_stream(duration_s: float = STREAM_S) -> dict[str, np.ndarray]:
    """t, Ft, Fn, d1, d2 of a simulated TLRE (paper model, 300 N, 10 um/s), sampled at 1024 Hz."""
    from rigctl.model import Drive, Simulator, build_model

    res = Simulator(build_model("paper")).run(
        Drive.constant(fn_N=300.0, velocity_m_s=1e-5, duration_s=duration_s))
    return {"t_s": res.t_s, "ft_N": res.ft_N, "fn_N": res.fn_N, "d1_m": res.d1_m, "d2_m": res.d2_m}


def blocks(stream: dict[str, np.ndarray], block_samples: int = BLOCK_SAMPLES,
           rate_hz: float = RATE_HZ) -> Iterator[dict[str, np.ndarray]]:
    """The stream cut into blocks, repeated for ever with rig time running on."""
    n = int(stream["t_s"].shape[0])
    period_s = n / rate_hz
    loop = 0
    while True:
        for i in range(0, n - block_samples + 1, block_samples):
            b = {k: v[i:i + block_samples] for k, v in stream.items()}
            b["t_s"] = b["t_s"] - stream["t_s"][0] + loop * period_s
            yield b
        loop += 1


def rss_bytes() -> int:
    """Resident memory of this process (Linux /proc; 0 elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


@dataclass
class SoakReport:
    redraws: int = 0
    samples: int = 0
    rig_time_s: float = 0.0
    wall_s: float = 0.0
    binding: str = ""
    python: str = ""
    refcounts: list[dict[str, float]] = field(default_factory=list)
    """At each checkpoint: redraw, None, True, False, rss_bytes."""
    redraw_ms_median: float = 0.0
    redraw_ms_p99: float = 0.0
    paint_ms_median: float = 0.0
    paint_ms_p99: float = 0.0

    def drift(self, key: str, after: int = 1) -> float:
        """Change of ``key`` from the checkpoint ``after`` (post warm-up) to the last."""
        return self.refcounts[-1][key] - self.refcounts[after][key]


def run_soak(redraws: int = 2000, fps: float = 30.0, checkpoint_every: int = 250,
             warmup: int = 100, prefeed_s: float = 0.0, size: tuple[int, int] = (900, 500),
             stream: dict[str, np.ndarray] | None = None) -> SoakReport:
    """Feed ``1024/fps`` samples per redraw, redraw and paint, ``redraws`` times (as fast as it goes).

    ``prefeed_s``: rig time fed before the first redraw (the benchmark's hour of data).
    """
    from PySide6.QtWidgets import QApplication

    from rigctl.gui.live_plot import LivePlot
    from rigctl.gui.selfcheck import binding_name

    app = QApplication.instance() or QApplication([sys.argv[0]])
    stream = stream if stream is not None else simulated_stream()
    live = LivePlot(rate_hz=RATE_HZ)
    live.resize(*size)
    live.show()
    source = blocks(stream)
    report = SoakReport(binding=binding_name(), python=sys.version.split()[0])
    per_redraw = RATE_HZ / fps
    fed = 0
    if prefeed_s > 0:
        chunk: list[dict[str, np.ndarray]] = []
        while fed < prefeed_s * RATE_HZ:
            b = next(source)
            chunk.append(b)
            fed += len(b["t_s"])
            if len(chunk) >= 256:
                live.feed(chunk)
                chunk = []
        live.feed(chunk)
    start_fed = fed
    redraw_ms: list[float] = []
    paint_ms: list[float] = []
    t_wall = time.perf_counter()

    def checkpoint(k: int) -> None:
        report.refcounts.append({"redraw": k, "None": sys.getrefcount(None),
                                 "True": sys.getrefcount(True), "False": sys.getrefcount(False),
                                 "rss_bytes": rss_bytes()})

    checkpoint(0)
    for k in range(1, redraws + 1):
        target = start_fed + round(k * per_redraw)
        new = []
        while fed < target:
            b = next(source)
            new.append(b)
            fed += len(b["t_s"])
        live.feed(new)
        t0 = time.perf_counter()
        live.redraw()
        t1 = time.perf_counter()
        live.glw.viewport().repaint()  # paint now, through pyqtgraph's item painters
        app.processEvents()
        t2 = time.perf_counter()
        if k > warmup:
            redraw_ms.append(1e3 * (t1 - t0))
            paint_ms.append(1e3 * (t2 - t1))
        if k in (warmup, redraws) or k % checkpoint_every == 0:
            checkpoint(k)
    report.wall_s = time.perf_counter() - t_wall
    report.redraws = live.redraws
    report.samples = live.samples
    report.rig_time_s = fed / RATE_HZ
    if redraw_ms:
        report.redraw_ms_median = float(np.median(redraw_ms))
        report.redraw_ms_p99 = float(np.percentile(redraw_ms, 99))
        report.paint_ms_median = float(np.median(paint_ms))
        report.paint_ms_p99 = float(np.percentile(paint_ms, 99))
    live.close()
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rigctl.gui.soak", description=__doc__)
    parser.add_argument("--redraws", type=int, default=2000)
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--prefeed-s", type=float, default=0.0, help="rig time fed before redrawing")
    parser.add_argument("--size", default="900x500", help="window size WxH in pixels")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    if args.redraws < 1 or not args.fps > 0:
        parser.error("--redraws must be >= 1 and --fps > 0")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(f"--size must be WIDTHxHEIGHT, got {args.size!r}")
    report = run_soak(args.redraws, args.fps, prefeed_s=args.prefeed_s, size=(width, height))
    if args.json:
        print(json.dumps(asdict(report)))
    else:
        print(f"{report.redraws} redraws, {report.samples} samples, {report.binding}, "
              f"None drift {report.drift('None'):+.0f}, True {report.drift('True'):+.0f}, "
              f"False {report.drift('False'):+.0f}; redraw {report.redraw_ms_median:.2f} ms, "
              f"paint {report.paint_ms_median:.2f} ms (median)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
