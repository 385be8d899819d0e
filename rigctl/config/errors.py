"""The configuration error."""

from __future__ import annotations

from rigctl.errors import InputError


class ConfigError(InputError):
    """An invalid configuration; the message names the file and the dotted key (``key``)."""

    def __init__(self, message: str, *, key: str = "") -> None:
        self.key = key
        super().__init__(message)
