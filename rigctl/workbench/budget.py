"""One budget for a model search: evaluations and/or wall seconds, cancel, progress with an ETA.

A :class:`Budget` is what a search spends and the one thing that stops it: a limit on simulations
(evaluations of the model on the data), a limit on wall seconds, or both, whichever comes first.
It measures the cost of an evaluation as the search runs (wall seconds per evaluation, with the
search's workers running in parallel), so it can say how many evaluations the time left still buys
(:meth:`Budget.evaluations_left`) and how long the rest will take (:meth:`Budget.eta_s`).

Cancelling (:meth:`Budget.cancel`, from another thread: a GUI's Cancel button or a signal handler)
sets an event the search checks between evaluations (:meth:`Budget.check` raises
:class:`SearchCancelledError`), so a search ends within about one evaluation's time of it.
Progress goes to an optional callback ``(fraction_done, eta_s, message)``.

The clock is injectable (``clock``: monotonic seconds), so that the accounting is tested without
waiting.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from rigctl.workbench.interrupts import raise_if_signalled

Progress = Callable[[float, float, str], None]
"""A progress callback: (fraction of the budget done, estimated seconds left, message)."""


class SearchCancelledError(Exception):
    """The search was cancelled (:meth:`Budget.cancel`) before it ended."""


@dataclass
class Budget:
    """Evaluations and/or wall seconds a search may spend (None: no limit of that kind)."""

    max_evaluations: int | None = None
    max_wall_s: float | None = None
    progress: Progress | None = None
    clock: Callable[[], float] = time.monotonic
    cancel_event: threading.Event = field(default_factory=threading.Event)
    used: int = 0
    """Evaluations spent so far."""
    _t0: float | None = None

    def __post_init__(self) -> None:
        if self.max_evaluations is not None and self.max_evaluations < 1:
            raise ValueError(f"max_evaluations must be at least 1, not {self.max_evaluations}")
        if self.max_wall_s is not None and not self.max_wall_s > 0.0:
            raise ValueError(f"max_wall_s must be positive, not {self.max_wall_s}")

    def start(self) -> None:
        """Start the wall clock (done by the first :meth:`spend` or :attr:`elapsed_s` otherwise)."""
        if self._t0 is None:
            self._t0 = self.clock()

    @property
    def elapsed_s(self) -> float:
        """Wall seconds since :meth:`start`."""
        self.start()
        assert self._t0 is not None
        return self.clock() - self._t0

    def spend(self, n: int = 1) -> None:
        """Count ``n`` evaluations as spent."""
        self.start()
        self.used += int(n)

    @property
    def seconds_per_evaluation(self) -> float:
        """Measured wall seconds per evaluation so far (NaN before any)."""
        return self.elapsed_s / self.used if self.used else math.nan

    def evaluations_left(self) -> float:
        """Evaluations the budget still allows: the count left, and what the time left buys at
        the measured cost per evaluation (inf where neither limits it yet)."""
        left = math.inf
        if self.max_evaluations is not None:
            left = float(max(self.max_evaluations - self.used, 0))
        if self.max_wall_s is not None:
            t_left = max(self.max_wall_s - self.elapsed_s, 0.0)
            cost = self.seconds_per_evaluation
            if t_left <= 0.0:
                left = 0.0
            elif math.isfinite(cost) and cost > 0.0:
                left = min(left, math.floor(t_left / cost))
        return left

    def time_binds(self) -> bool:
        """Whether the wall limit is what limits the evaluations left: a limit on seconds is set
        and the time left buys fewer evaluations than the count left allows (a search that
        stops on its budget now stops on its time)."""
        if self.max_wall_s is None:
            return False
        count_left = math.inf if self.max_evaluations is None else \
            float(max(self.max_evaluations - self.used, 0))
        return self.evaluations_left() < count_left

    def exhausted(self) -> bool:
        """Nothing is left: the evaluations are spent or the time is up."""
        return self.evaluations_left() <= 0.0

    @property
    def fraction_done(self) -> float:
        """Share of the budget spent (the larger of evaluations and time), 0 to 1; NaN where the
        budget has no limit."""
        parts = []
        if self.max_evaluations is not None:
            parts.append(self.used / self.max_evaluations)
        if self.max_wall_s is not None:
            parts.append(self.elapsed_s / self.max_wall_s)
        return min(max(parts), 1.0) if parts else math.nan

    def eta_s(self, evaluations: float | None = None) -> float:
        """Estimated wall seconds left: ``evaluations`` more (default: what the budget allows) at
        the measured cost per evaluation, at most the time left (NaN before the first evaluation
        where no time limit bounds it)."""
        n = self.evaluations_left() if evaluations is None else evaluations
        est = n * self.seconds_per_evaluation if self.used else math.nan
        if self.max_wall_s is not None:
            t_left = max(self.max_wall_s - self.elapsed_s, 0.0)
            est = t_left if math.isnan(est) else min(est, t_left)
        return est

    def report(self, message: str, evaluations_left: float | None = None) -> None:
        """Send ``(fraction_done, eta_s, message)`` to the progress callback, if any.
        ``evaluations_left``: the search's own estimate where it expects to end before the budget
        does."""
        if self.progress is not None:
            eta = self.eta_s(evaluations_left)
            done = self.fraction_done
            if evaluations_left is not None and self.used:
                done = self.used / (self.used + evaluations_left)
            self.progress(done, eta, message)

    def cancel(self) -> None:
        """Ask the search to stop (thread-safe); it raises :class:`SearchCancelledError` at its next
        check."""
        self.cancel_event.set()

    @property
    def cancelled(self) -> bool:
        return self.cancel_event.is_set()

    def check(self) -> None:
        """Raise :class:`SearchCancelledError` if the search was cancelled, and a Ctrl-C or
        SIGTERM noted but not yet raised (:mod:`rigctl.workbench.interrupts`)."""
        raise_if_signalled()
        if self.cancel_event.is_set():
            raise SearchCancelledError("search cancelled")


def said(say: Callable[[str], None]) -> Progress:
    """A progress callback that says each report in words through ``say`` (a CLI's stderr, a
    GUI's status line): the stage, the share of the budget spent and the time left."""

    def progress(done: float, eta_s: float, message: str) -> None:
        share = f"{done:.0%}" if math.isfinite(done) else "?"
        left = f"about {eta_s:.0f} s left" if math.isfinite(eta_s) else "time left not known yet"
        say(f"  {message} ({share} of the search budget, {left})")

    return progress
