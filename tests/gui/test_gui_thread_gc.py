"""Cyclic garbage is collected in the GUI thread only, while a window is up (rigctl.gui.gui_thread_gc).

A soak of the GUI tests deadlocked in a generation-2 collection started by a worker thread: it was
deleting a closed window's QMenu and QActions while the GUI thread, holding the GIL, waited for a Qt
lock the worker held."""

from __future__ import annotations

import gc
import threading

from PySide6.QtCore import QObject

from rigctl.gui import gui_thread_gc
from rigctl.gui.gui_thread_gc import collecting_in_gui_thread, gui_thread_collection

CHURN = 20_000
"""Containers a worker allocates: some 28 times the generation-0 threshold of 700."""


class _InACycle(QObject):
    """A QObject only the cyclic collector can free; records the thread that deleted it."""

    def __init__(self, deleted_in: list[str]) -> None:
        super().__init__()
        self.deleted_in = deleted_in
        self.me = self

    def __del__(self) -> None:
        self.deleted_in.append(threading.current_thread().name)


def _cycle_then_churn_in_a_worker(kept: list[list[int]]) -> list[str]:
    """A QObject in a cycle, then a worker allocating ``CHURN`` containers kept in ``kept`` (the
    heap grows, as in a run; the collector's counts pass their thresholds)."""
    gc.collect()
    deleted_in: list[str] = []
    _InACycle(deleted_in)  # unreachable at once, except through its own cycle
    worker = threading.Thread(target=lambda: kept.extend([i] for i in range(CHURN)), name="worker")
    worker.start()
    worker.join()
    assert len(kept) == CHURN
    return deleted_in


def test_a_worker_thread_does_not_collect_qt_objects(qtbot) -> None:
    assert collecting_in_gui_thread()  # the package's fixture sets it, as `rigctl gui` does
    deleted_in = _cycle_then_churn_in_a_worker(kept := [])
    assert deleted_in == []  # the worker's allocations started no collection
    qtbot.waitUntil(lambda: deleted_in == ["MainThread"], timeout=5000)  # the collector's timer
    kept.clear()


def test_with_automatic_collection_a_worker_would_collect_them(qtbot) -> None:
    """Why the policy exists (and that the test above can fail): with Python's automatic collection
    the worker's allocations collect the QObject in the worker."""
    gc.enable()
    try:
        deleted_in = _cycle_then_churn_in_a_worker([])
    finally:
        gc.disable()
    assert deleted_in == ["worker"]


def test_a_nested_window_leaves_the_policy_in_force() -> None:
    """A second window's ``gui_thread_collection`` (the screenshot inside a test session, a
    dialog's own event loop) must not turn automatic collection back on when it ends."""
    with gui_thread_collection():
        pass
    assert collecting_in_gui_thread()


def test_the_collection_is_put_back_as_it_was(monkeypatch) -> None:
    """A program that had automatic collection off keeps it off after the window."""
    monkeypatch.setattr(gui_thread_gc, "_collector", None)  # as before any window
    assert not gc.isenabled()  # the package's policy has it off
    with gui_thread_collection():
        assert collecting_in_gui_thread()
    assert not gc.isenabled()
