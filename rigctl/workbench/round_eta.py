"""How long the rest of a step's screens, full fits or refits will take, from the parts already
done.

Each part of a selection step (:mod:`rigctl.workbench.selection`: the screens of the singles, of
the pairs, the full fits, the backward refits) is a list of items with a relative cost each (equal
where nothing tells them apart). An item's wall time is roughly its number of simulations times
that cost, and the number of simulations varies less between items than the cost does (the same
search with the same budget), so the time left is estimated as the wall time so far scaled by the
cost still to do over the cost done::

    t_left = t_elapsed * sum(cost of the candidates left) / sum(cost of the candidates done)

The wall time already reflects how many workers run at once, so no worker count appears. It is an
estimate: said as "about", rounded, and not given before the first fit ends.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence


def eta_s(elapsed_s: float, done_costs: Sequence[float], left_costs: Sequence[float]) -> float:
    """Seconds left (the module's formula); NaN before any cost is done, 0 when nothing is left."""
    left = float(sum(left_costs))
    if left <= 0.0:
        return 0.0
    done = float(sum(done_costs))
    if done <= 0.0 or not math.isfinite(elapsed_s):
        return math.nan
    return elapsed_s * left / done


def say_duration(seconds: float) -> str:
    """"about 40 s", "about 3 min", "about 1.2 h" (an estimate, rounded as one)."""
    if not math.isfinite(seconds):
        return "unknown"
    if seconds < 90.0:
        return f"about {max(round(seconds / 5.0) * 5, 5):.0f} s"
    if seconds < 5400.0:
        return f"about {round(seconds / 60.0):.0f} min"
    return f"about {seconds / 3600.0:.1f} h"


class RoundClock:
    """Counts the candidate fits of one round as they end and says how far the round is."""

    def __init__(self, costs: Sequence[float], clock: Callable[[], float] = time.monotonic) -> None:
        self._costs = [max(float(c), 0.0) for c in costs]
        self._done: set[int] = set()
        self._clock = clock
        self._t0 = clock()

    def finished(self, i: int) -> str:
        """Mark candidate ``i`` done; "[k/n, about T left in this round]"."""
        self._done.add(i)
        n, k = len(self._costs), len(self._done)
        if k >= n:
            return f"[{k}/{n}]"
        done = [self._costs[j] for j in self._done]
        left = [c for j, c in enumerate(self._costs) if j not in self._done]
        t_left = eta_s(self._clock() - self._t0, done, left)
        return f"[{k}/{n}, {say_duration(t_left)} left in this round]"
