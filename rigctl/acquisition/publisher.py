"""Live subscribers (plots, GUI, live analysis) that can never slow the recorder.

``publish`` is O(number of subscribers) and never blocks: each subscription is a bounded deque; a
subscriber that does not keep up loses its own oldest items, and the loss is counted on its
subscription (``dropped``), never hidden and never felt by the writer.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any


class Subscription:
    """One subscriber's bounded mailbox."""

    def __init__(self, topic: str, maxlen: int) -> None:
        self.topic = topic
        self._items: deque[Any] = deque(maxlen=maxlen)
        self._cond = threading.Condition()
        self.dropped = 0
        self.closed = False

    def _put(self, item: Any) -> None:
        with self._cond:
            if len(self._items) == self._items.maxlen:
                self.dropped += 1
            self._items.append(item)
            self._cond.notify()

    def get(self, timeout_s: float | None = None) -> Any | None:
        """The oldest item, waiting up to ``timeout_s``; None if nothing came."""
        with self._cond:
            if not self._items:
                self._cond.wait(timeout_s)
            return self._items.popleft() if self._items else None

    def drain(self) -> list[Any]:
        """Every item waiting, oldest first."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            return items


class Publisher:
    """Topic-based fan-out to subscriptions."""

    def __init__(self) -> None:
        self._subs: list[Subscription] = []
        self._lock = threading.Lock()

    def subscribe(self, topic: str, maxlen: int = 256) -> Subscription:
        if maxlen < 1:
            raise ValueError("a subscription holds at least one item")
        sub = Subscription(topic, maxlen)
        with self._lock:
            self._subs.append(sub)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            if sub in self._subs:
                self._subs.remove(sub)
        sub.closed = True

    def publish(self, topic: str, item: Any) -> None:
        with self._lock:
            subs = [s for s in self._subs if s.topic == topic]
        for s in subs:
            s._put(item)

    @property
    def dropped(self) -> int:
        with self._lock:
            return sum(s.dropped for s in self._subs)
