"""Fixtures shared by the GUI tests."""

from __future__ import annotations

import gc
import math
from collections.abc import Iterator

import pytest

from rigctl.config.loader import default_config
from rigctl.gui.gui_thread_gc import gui_thread_collection
from rigctl.rigs import OpenRig, open_rig


@pytest.fixture
def rig() -> Iterator[OpenRig]:
    """A simulated rig at ``--speed max``; its emergency stops are released after the test (a test
    that presses F12 leaves them latched)."""
    with open_rig("sim", default_config(), speed=math.inf) as r:
        yield r
        for stage in (r.devices.tangential_stage, r.devices.normal_stage):
            stage.emergency_stop_registry.reset()


@pytest.fixture(scope="package", autouse=True)
def _gc_in_gui_thread(qapp: object) -> Iterator[None]:
    """The GUI's collection policy (rigctl.gui.gui_thread_gc), as ``rigctl gui`` sets it: a worker
    thread never collects the tests' Qt objects (one clean-clone run crashed, and a soak of these
    tests deadlocked, in collections started by a run thread). Automatic collection is back on for
    the tests after these."""
    with gui_thread_collection():
        yield


@pytest.fixture(autouse=True)
def _collect_after_each_test() -> Iterator[None]:
    """Each test's reference cycles are collected when it ends, in the main thread with its run
    threads gone (the GUI-thread collector's timer runs only while a test processes events)."""
    yield
    gc.collect()


@pytest.fixture(autouse=True)
def _no_modal_question(monkeypatch: pytest.MonkeyPatch) -> None:
    """A modal question (``QMessageBox.question``) answers Yes at once in the tests instead of
    waiting for a click: a test that failed with a run going used to hang at teardown in the
    window's "abort and close?" dialog, where no timeout reaches (Qt's own event loop); Yes aborts
    the run to the safe state, as an operator closing the window would. A test of a question
    replaces the panel's ``_ask`` itself."""
    from PySide6.QtWidgets import QMessageBox

    def answer_yes(*_args: object, **_kwargs: object) -> QMessageBox.StandardButton:
        return QMessageBox.StandardButton.Yes

    monkeypatch.setattr(QMessageBox, "question", answer_yes)
