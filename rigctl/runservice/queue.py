"""A queue of protocol runs in the run service: run them one after another, each with its own file.

Like bluesky-queueserver's plan queue, the queue lives in the process that owns the rig (the run
service), so it survives the window: a window that closes or dies leaves the queue running, and
another window connecting sees it. This module is the queue's bookkeeping only (no threads, no I/O);
the service calls it under its lock and starts the runs it hands out.

Rules:

* Items run in order; each is a :class:`~rigctl.runservice.wire.JobSpec` with its own parameters
  and run file. Only pending items may be removed or moved.
* A run that ends ``completed`` starts the next pending item; the queue is done when none is left.
* A run that ends otherwise (aborted, failed, refused by the dry run, not started) **stops** the
  queue: the items after it stay pending, and the queue's message says which run stopped it and how
  many were not started.
* Aborting the queue aborts its current run (the service does that: safe state, file ``aborted``)
  and drops every pending item (status ``dropped``); nothing of theirs is created.
* Pause and resume act on the current run (the stages hold; the queue waits with it).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from rigctl.errors import InputError
from rigctl.runservice.wire import JobSpec

PENDING, RUNNING, COMPLETED, DROPPED = "pending", "running", "completed", "dropped"


@dataclass(frozen=True)
class QueueItem:
    item: int
    """Identifier, unique in the service's life."""
    spec: JobSpec
    status: str = PENDING
    """pending, running, completed, aborted, failed, refused, error or dropped."""
    message: str = ""


@dataclass(frozen=True)
class QueueState:
    """What the windows show: the items in order, whether the queue runs, its last message."""

    items: tuple[QueueItem, ...] = ()
    running: bool = False
    message: str = ""


class RunQueue:
    """The queue's items and rules (not thread-safe: the service calls it under its lock)."""

    def __init__(self) -> None:
        self._items: list[QueueItem] = []
        self._next_id = 1
        self.running = False
        self.message = ""

    def state(self) -> QueueState:
        return QueueState(tuple(self._items), self.running, self.message)

    def _index(self, item: int) -> int:
        for i, it in enumerate(self._items):
            if it.item == item:
                return i
        raise InputError(f"queue: no item {item}")

    def add(self, spec: JobSpec) -> int:
        """Append a run; refused (InputError) without a run file or with one another item has."""
        if spec.dry:
            raise InputError("queue: a dry run cannot be queued")
        if not spec.out:
            raise InputError(f"queue: the {spec.protocol} run has no run file")
        for it in self._items:
            if it.spec.out == spec.out and it.status in (PENDING, RUNNING):
                raise InputError(f"queue: item {it.item} ({it.spec.protocol}) already records "
                                 f"to {spec.out}")
        item = self._next_id
        self._next_id += 1
        self._items.append(QueueItem(item, dataclasses.replace(spec, queue_item=item)))
        return item

    def remove(self, item: int) -> None:
        i = self._index(item)
        if self._items[i].status == RUNNING:
            raise InputError(f"queue: item {item} is running; abort it instead")
        del self._items[i]

    def move(self, item: int, delta: int) -> None:
        """Move a pending item up (-1) or down (+1) among the pending items."""
        if delta not in (-1, 1):
            raise InputError(f"queue: move by -1 or +1, got {delta!r}")
        i = self._index(item)
        j = i + delta
        if self._items[i].status != PENDING:
            raise InputError(f"queue: item {item} is {self._items[i].status}; only pending items move")
        if not 0 <= j < len(self._items) or self._items[j].status != PENDING:
            return  # already first/last of the pending ones
        self._items[i], self._items[j] = self._items[j], self._items[i]

    def _set(self, i: int, status: str, message: str = "") -> None:
        self._items[i] = dataclasses.replace(self._items[i], status=status, message=message)

    def _next_pending(self) -> JobSpec | None:
        for i, it in enumerate(self._items):
            if it.status == PENDING:
                self._set(i, RUNNING)
                return it.spec
        return None

    def start(self) -> JobSpec | None:
        """Start the queue: the first pending item's spec (now running), or None if none is left."""
        if self.running:
            return None
        spec = self._next_pending()
        if spec is None:
            self.message = "queue: nothing pending to run"
            return None
        self.running = True
        self.message = "queue running"
        return spec

    def finished(self, item: int, status: str, message: str) -> JobSpec | None:
        """A queued run ended with ``status`` (completed, aborted, failed, refused, error): the next
        item's spec to start, or None (the queue is done or stopped; :attr:`message` says which)."""
        i = self._index(item)
        self._set(i, status, message)
        if not self.running:
            return None
        if status == COMPLETED:
            spec = self._next_pending()
            if spec is not None:
                return spec
            self.running = False
            done = sum(1 for it in self._items if it.status == COMPLETED)
            self.message = f"queue completed: {done} run(s) completed"
            return None
        self.running = False
        left = sum(1 for it in self._items if it.status == PENDING)
        it = self._items[i]
        self.message = (f"queue stopped: item {item} ({it.spec.protocol}) ended {status}"
                        + (f": {message}" if message else "")
                        + f"; {left} run(s) not started (still queued)")
        return None

    def abort(self, reason: str) -> bool:
        """Stop the queue and drop every pending item; True if a queued run is going (to abort)."""
        dropped = 0
        for i, it in enumerate(self._items):
            if it.status == PENDING:
                self._set(i, DROPPED, reason)
                dropped += 1
        going = any(it.status == RUNNING for it in self._items)
        self.running = False
        self.message = f"queue aborted ({reason}): {dropped} run(s) dropped"
        return going

    def clear(self) -> None:
        """Remove the items that have ended (completed, aborted, failed, dropped, ...)."""
        self._items = [it for it in self._items if it.status in (PENDING, RUNNING)]
