"""Warnings of a run as events for the window: log records and the acquisition's drop counters.

The acquisition, the drivers and the simulators say what goes wrong during a run through
:mod:`logging` (a probe over range, a stage position that cannot be read, the writer's queue full,
a failed device). :class:`WarningForwarder` hands each such record (WARNING and above, from
``rigctl``, ``experiments``, ``drivers`` and ``sim_devices``) to a callback as ``(level, text)``;
the run service broadcasts them as ``log`` messages, the in-process run panel emits them as a signal.
:func:`drop_events` turns growing drop counts of :class:`~rigctl.acquisition.AcquisitionStats` into
the same kind of event.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from typing import Any

SOURCES = ("rigctl", "experiments", "drivers", "sim_devices")
"""Loggers whose warnings are forwarded (and their children)."""
_SKIP = ("rigctl.runservice",)
"""Loggers whose records already reach the window another way."""


class WarningForwarder(logging.Handler):
    """A logging handler that calls ``emit_event(level, text)`` for WARNING and above."""

    def __init__(self, emit_event: Callable[[str, str], None], level: int = logging.WARNING) -> None:
        super().__init__(level)
        self._emit_event = emit_event

    def emit(self, record: logging.LogRecord) -> None:
        name = record.name
        if not any(name == s or name.startswith(s + ".") for s in SOURCES):
            return
        if any(name == s or name.startswith(s + ".") for s in _SKIP):
            return
        try:
            text = record.getMessage()
        except Exception:  # a bad format string must not break the run
            text = str(record.msg)
        self._emit_event("error" if record.levelno >= logging.ERROR else "warning", text)

    def install(self) -> WarningForwarder:
        """Attach to the source loggers (each keeps propagating to the root as before)."""
        for s in SOURCES:
            logging.getLogger(s).addHandler(self)
        return self

    def remove(self) -> None:
        for s in SOURCES:
            logging.getLogger(s).removeHandler(self)


_DROP_COUNTERS = (
    ("daq_dropped", "samples lost by the DAQ before reaching the host"),
    ("queue_dropped_samples", "samples refused by the full writer queue (not in the run file)"),
    ("frames_dropped", "camera frames lost by the camera"),
    ("queue_dropped_frames", "camera frames not recorded (the writer could not keep up)"),
)


def drop_events(stats: Any, seen: dict[str, int]) -> Iterator[tuple[str, str]]:
    """``(level, text)`` for each drop counter of ``stats`` that grew since ``seen`` (updated)."""
    for name, what in _DROP_COUNTERS:
        now = int(getattr(stats, name, 0))
        before = seen.get(name, 0)
        if now > before:
            yield "warning", f"dropped data: {now - before} {what} ({now} in this run)"
        seen[name] = now
