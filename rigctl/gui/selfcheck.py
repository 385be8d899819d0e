"""Start-up self-check of the Qt binding: does a void Qt call leak a reference to None (or a bool)?

PySide6 6.12.0 on CPython 3.11 drops one reference to ``None`` on every Qt call that returns void
(``QRectF.setHeight``); a live plot makes thousands such calls a second and the interpreter aborts with
``Fatal Python error: none_dealloc`` once ``None``'s count reaches zero. On CPython >= 3.12 ``None``,
``True`` and ``False`` are immortal and the defect is harmless; on 3.11 the window must not start.
``rigctl gui`` runs :func:`check_binding` before it opens a window and refuses to start if it fails.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

CALLS = 200
"""Calls made by the check (microseconds of work); references it finds lost are given back."""


@dataclass(frozen=True)
class BindingCheck:
    binding: str
    calls: int
    none_drift: int
    true_drift: int
    false_drift: int

    @property
    def leaking(self) -> bool:
        """A loss of at least one reference per two calls (the defect loses exactly one per call)."""
        worst = min(self.none_drift, self.true_drift, self.false_drift)
        return worst <= -self.calls // 2

    def message(self) -> str:
        return (f"the Qt binding {self.binding} loses references to None/True/False on Qt calls "
                f"({self.none_drift}/{self.true_drift}/{self.false_drift} after {self.calls} calls) "
                f"and would abort mid-run on CPython {sys.version_info.major}.{sys.version_info.minor}; "
                "install the pinned PySide6-Essentials==6.11.3 (pip install -e .)")


def binding_name() -> str:
    import PySide6

    return f"PySide6 {PySide6.__version__}"


def _qt_calls() -> tuple[Callable[[], object], Callable[[], object]]:
    """A void call (setHeight) and a bool-returning call (isEmpty) on a QRectF."""
    from PySide6.QtCore import QRectF

    r = QRectF(0.0, 0.0, 1.0, 1.0)
    return (lambda: r.setHeight(1.0)), (lambda: r.isEmpty())


def check_binding(calls: int = CALLS,
                  probes: tuple[Callable[[], object], Callable[[], object]] | None = None) -> BindingCheck:
    """Count None/True/False references before and after ``calls`` void and bool-returning Qt calls.

    ``probes`` replaces the two Qt calls (tests use it to check that a leak is detected).
    """
    void_call, bool_call = probes if probes is not None else _qt_calls()
    refs = sys.getrefcount
    none0, true0, false0 = refs(None), refs(True), refs(False)
    for _ in range(calls):
        void_call()
        bool_call()
    none1, true1, false1 = refs(None), refs(True), refs(False)
    result = BindingCheck(binding_name(), calls, none1 - none0, true1 - true0, false1 - false0)
    for obj, drift in ((None, result.none_drift), (True, result.true_drift), (False, result.false_drift)):
        _give_back(obj, -drift)
    return result


def _give_back(obj: object, lost: int) -> None:
    """Restore ``lost`` references the check's own calls dropped (so the refusing process exits cleanly)."""
    if lost <= 0:
        return
    import ctypes

    incref = ctypes.pythonapi.Py_IncRef
    incref.argtypes = [ctypes.py_object]
    for _ in range(lost):
        incref(obj)
