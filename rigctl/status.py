"""A run's status (light: the CLI imports it without the HDF5 stack)."""

from __future__ import annotations

from enum import StrEnum


class RunStatus(StrEnum):
    """A run's status; its value is the text stored in the run file's ``entry/status`` and in JSON.

    A run file is ``running`` while it is written and ends ``completed``, ``aborted`` (by the operator,
    a signal or Ctrl-C) or ``failed`` (a device, a limit trip, the disk), with the error text.
    """

    RUNNING = "running"
    COMPLETED = "completed"
    ABORTED = "aborted"
    FAILED = "failed"
