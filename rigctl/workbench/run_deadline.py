"""A time limit for a whole ``diagnose --auto`` run, shared by its fits and screens.

A run is many searches: the model's own fit, then per forward step a screen of every candidate set
and up to six full fits, then backward elimination. Each fit has its own limit (``--timeout``), but
six fits of a slow model (``presliding``, ``rate_state``: seconds per simulation) at that limit
make a run of half an hour. A :class:`RunDeadline` bounds the run instead:

- **a fit's share** (:meth:`RunDeadline.share_s`): a fit may spend the time left divided by the
  number of fits its step still has to run plus one, the one kept back for what follows (the next
  step, backward elimination, the report). A fit that reaches its share ends with its best point
  so far, judged like any other;
- **a hard stop** at the limit itself: :attr:`RunDeadline.cancel` is set when the limit is reached
  (or when the user's own cancel event is set), and every search and screen of the run watches it.
  The selection then ends with the model it has (:mod:`rigctl.workbench.selection`), and says so.

The clock is injectable (``clock``: monotonic seconds), so that the shares are tested without
waiting.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

DEFAULT_RUN_S = 540.0
"""The default limit of a whole ``--auto`` run: nine minutes, so that with the data's preparation
and the final report a run at the rig ends within ten (an operator waits for it)."""
WATCH_PERIOD_S = 0.1
"""How often the watcher looks at the clock and the user's cancel event: a run ends within about
this plus one evaluation of its limit."""


class RunDeadline:
    """The time left of a run limited to ``limit_s`` wall seconds from its creation (None: no
    limit; shares are then None and :attr:`cancel` follows the user's event only)."""

    def __init__(self, limit_s: float | None, user_cancel: threading.Event | None = None, *,
                 clock: Callable[[], float] = time.monotonic, watch: bool = True) -> None:
        if limit_s is not None and not limit_s > 0.0:
            raise ValueError(f"the run's time limit must be positive, not {limit_s} s")
        self.limit_s = limit_s
        self.clock = clock
        self._t0 = clock()
        self.user_cancel = user_cancel
        self.cancel = threading.Event()
        """Set at the limit or when the user's cancel event is set: what the run's searches
        watch."""
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        if watch and (limit_s is not None or user_cancel is not None):
            self._thread = threading.Thread(target=self._watch, name="run-deadline", daemon=True)
            self._thread.start()

    def left_s(self) -> float | None:
        """Wall seconds left (at least 0; None without a limit)."""
        if self.limit_s is None:
            return None
        return max(self.limit_s - (self.clock() - self._t0), 0.0)

    def passed(self) -> bool:
        """Whether the limit is reached."""
        left = self.left_s()
        return left is not None and left <= 0.0

    def share_s(self, fits_left: int) -> float | None:
        """The wall seconds one of ``fits_left`` fits still to run may spend: the time left over
        ``fits_left + 1`` (one share kept for what follows; None without a limit)."""
        left = self.left_s()
        return None if left is None else left / (max(fits_left, 1) + 1)

    @property
    def user_cancelled(self) -> bool:
        """Whether the user (not the limit) cancelled the run."""
        return self.user_cancel is not None and self.user_cancel.is_set()

    def expired(self) -> bool:
        """Whether the limit, not the user, ends the run (what a cancelled search was stopped
        by)."""
        return self.passed() and not self.user_cancelled

    def _watch(self) -> None:
        while not self._done.wait(WATCH_PERIOD_S):
            if self.user_cancelled or self.passed():
                self.cancel.set()
                return

    def close(self) -> None:
        """Stop watching (the run ended)."""
        self._done.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)

    def __enter__(self) -> RunDeadline:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
