"""Garbage collection only in the GUI thread, while a window is up.

Python's cyclic collector runs in whichever thread happens to allocate when a generation's count
passes its threshold. A reference cycle holding Qt objects (pyqtgraph's items, a closed window's
widgets and menus) collected in a worker thread (the run thread, the live view's file-info worker)
deletes QObjects outside the GUI thread. The process then crashes, or deadlocks: the worker, inside
``QObject::~QObject`` with a Qt lock held, waits for the GIL, while the GUI thread, holding the GIL
in a deletion shiboken queued for it, waits for that lock. Both were seen in the GUI tests (a
segfault in a collection during a run, and a deadlock with a generation-2 collection in a worker).

So while a window is up, automatic collection is off and pyqtgraph's
:class:`~pyqtgraph.util.garbage_collector.GarbageCollector` collects on a timer in the GUI thread,
generation by generation with the thresholds Python had. Worker threads never collect; garbage
without cycles is freed by reference counting as always, in any thread.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

from pyqtgraph.util.garbage_collector import GarbageCollector

INTERVAL_S = 1.0
"""How often the GUI thread checks the collector's counts (pyqtgraph's default)."""

_collector: GarbageCollector | None = None
_was_enabled = True
"""Whether automatic collection was on when the collector was installed (restored after it)."""


def collect_in_gui_thread(interval_s: float = INTERVAL_S) -> GarbageCollector:
    """Turn automatic collection off and collect on a timer in this (the GUI) thread; idempotent.
    Call it from the GUI thread once a QApplication exists."""
    global _collector, _was_enabled
    if _collector is None:
        _was_enabled = gc.isenabled()
        _collector = GarbageCollector(interval=interval_s)
    return _collector


def restore_automatic_gc() -> None:
    """Stop the timer, collect once here and put automatic collection back as it was before
    :func:`collect_in_gui_thread` (the window is gone)."""
    global _collector
    if _collector is not None:
        _collector.timer.stop()
        _collector = None
    gc.collect()
    if _was_enabled:
        gc.enable()


@contextlib.contextmanager
def gui_thread_collection() -> Iterator[GarbageCollector]:
    """:func:`collect_in_gui_thread` for the body, :func:`restore_automatic_gc` after it; nested
    in a body where the policy is already in force, it leaves it in force."""
    installed_here = _collector is None
    collector = collect_in_gui_thread()
    try:
        yield collector
    finally:
        if installed_here:
            restore_automatic_gc()


def collecting_in_gui_thread() -> bool:
    """True while :func:`collect_in_gui_thread` is in force."""
    return _collector is not None and not gc.isenabled()
