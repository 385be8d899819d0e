"""The terminal progress of ``rigctl run``: a tqdm bar redrawn twice a second from the rig clock.

The bar counts planned rig seconds: the steps already done at their planned durations, plus the
time spent in the current step (capped at its estimate; a step that takes longer holds the bar, it
never runs past 100 %). Time while paused does not count, so the ETA neither drifts nor advances
while the operator holds the run; pause and resume are said on their own lines, and so are
warnings (log records go through ``tqdm.write``, never glued to the bar).
"""

from __future__ import annotations

import contextlib
import logging
import math
import shutil
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import IO, Any

from tqdm import tqdm

REDRAW_S = 0.5
"""Seconds between redraws (host time): often enough to look alive, rare enough to cost nothing."""


class RunProgress:
    """Progress of one protocol run; feed it :meth:`on_step` (the runner's progress callback) and
    :meth:`attach` (the acquisition, for its rig clock), or :meth:`tick` by hand in tests."""

    def __init__(self, step_estimates_s: Sequence[float], speed: float,
                 paused: Callable[[], bool], stream: IO[str] | None = None) -> None:
        self._est = [float(e) for e in step_estimates_s]
        self._speed = speed
        self._paused = paused
        self._total = total = sum(self._est)
        sized = shutil.get_terminal_size((0, 0)).columns > 0
        self.bar = tqdm(total=round(total, 1), unit="s", file=stream, dynamic_ncols=sized,
                        ncols=None if sized else 100,
                        bar_format="{desc} {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} s rig "
                                   "time{postfix}", leave=True)
        self._clock: Callable[[], float] | None = None
        self._step = 0
        self._step_t0 = float("nan")
        self._paused_s = 0.0
        self._pause_t0: float | None = None
        self._was_paused = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def attach(self, acquisition: Any) -> None:
        """Read the rig clock (device time of the latest sample) from ``acquisition.t_s``."""
        self._clock = lambda: float(acquisition.t_s)
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="run-progress", daemon=True)
            self._thread.start()

    def on_step(self, i: int, n: int, desc: str, elapsed_s: float, eta_s: float) -> None:
        """The runner's progress callback: step ``i`` of ``n`` starts now."""
        with self._lock:
            self._step = i
            self._step_t0 = self._now()
            self._paused_s = 0.0
            self._pause_t0 = None
            self.bar.set_description_str(f"[{i}/{n}] {desc[:40]}", refresh=False)
        self.tick()

    def tick(self) -> None:
        """Redraw from the rig clock."""
        with self._lock:
            now = self._now()
            paused = self._paused()
            if paused and not self._was_paused:
                self._pause_t0 = now
                tqdm.write("paused (SIGUSR2 or the GUI resumes)", file=self.bar.fp)
            elif not paused and self._was_paused:
                if self._pause_t0 is not None and not math.isnan(now):
                    self._paused_s += now - self._pause_t0
                self._pause_t0 = None
                tqdm.write("resumed", file=self.bar.fp)
            self._was_paused = paused
            done = sum(self._est[: max(self._step - 1, 0)])
            current = 0.0
            if (1 <= self._step <= len(self._est) and not math.isnan(now)
                    and not math.isnan(self._step_t0)):
                held = self._paused_s + ((now - self._pause_t0) if self._pause_t0 is not None
                                         else 0.0)
                current = min(max(now - self._step_t0 - held, 0.0), self._est[self._step - 1])
            self.bar.n = round(done + current, 1)
            left = max(self._total - self.bar.n, 0.0)
            wall = f", ~{left / self._speed:.0f} s wall" if self._speed < float("inf") else ""
            self.bar.set_postfix_str(("PAUSED, " if paused else "") + f"ETA {left:.0f} s{wall}",
                                     refresh=False)
            self.bar.refresh()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.bar.close()

    def _now(self) -> float:
        return self._clock() if self._clock is not None else float("nan")

    def _loop(self) -> None:
        while not self._stop.wait(REDRAW_S):
            with contextlib.suppress(Exception):  # a display must never stop a run
                self.tick()


class _TqdmHandler(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        with contextlib.suppress(Exception):
            tqdm.write(self.format(record))


@contextlib.contextmanager
def warnings_on_their_own_lines() -> Iterator[None]:
    """Route warning log records through ``tqdm.write`` while a bar is shown."""
    root = logging.getLogger()
    handler = _TqdmHandler(logging.WARNING)
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
