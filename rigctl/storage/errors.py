"""Errors of the run-file layer."""

from __future__ import annotations

from pathlib import Path


class StorageError(ValueError):
    """A run file that cannot be created or written (path, permission, space, HDF5 failure).

    A ``ValueError`` so that the CLI prints it as one line with exit status 2: the fix (another
    folder, free space, a new file name) is the user's.
    """

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)
