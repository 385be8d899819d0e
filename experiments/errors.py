"""Errors of experiment procedures (each names the step and what is wrong)."""

from __future__ import annotations

from rigctl.errors import InputError


class ProcedureError(RuntimeError):
    """A procedure could not go on (the runner brings the rig to a safe state)."""


class PlanError(InputError):
    """A protocol plan that violates a limit or has bad parameters (found by the dry run)."""


class ProtocolAborted(Exception):  # noqa: N818 - an outcome, not a fault
    """The operator (or a signal) aborted the run."""
