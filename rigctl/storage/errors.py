"""Errors of the run-file layer (:class:`rigctl.errors.StorageError`)."""

from __future__ import annotations

from rigctl.errors import StorageError

__all__ = ["StorageError"]
