"""rigctl's errors by kind, so that each caller catches only what it can handle.

Hierarchy::

    InputError (a ValueError)    what the user gave cannot be used; the CLI prints one line, exit 2
    +-- UsageError               a command line that does not make sense (rigctl.cli)
    +-- ConfigError              a configuration file or value (rigctl.config)
    +-- DataError                measured data that cannot be used (rigctl.data)
    +-- StorageError             a run file that cannot be created, read or written
    +-- PlanError                a protocol plan beyond a limit or with bad parameters (experiments)
    +-- ParameterError           (also a SimulationError) values the model cannot take (rigctl.model)
    +-- EffectPluginError        an effect plug-in that cannot be loaded (rigctl.model.plugins)
    +-- drivers' InvalidValueError, LimitError, SettingError

    DeviceError                  a device failed (drivers.errors: timeout, alarm, protocol, ...)

    SimulationError (a ValueError)  the model cannot be run with these values; the workbench skips
    +-- ParameterError              such a candidate instead of failing the whole fit

``InputError`` and ``DeviceError`` are the drivers' own classes (:mod:`drivers.errors`), re-exported
here: the drivers sit below rigctl and cannot import it. Any other exception is a programming error
and is never turned into a usage message or a skipped candidate.
"""

from __future__ import annotations

from pathlib import Path

from drivers.errors import DeviceError, InputError

__all__ = ["DeviceError", "InputError", "SimulationError", "StorageError", "UsageError"]


class UsageError(InputError):
    """A problem with what the user asked for on the command line; one line, exit code 2."""


class SimulationError(ValueError):
    """The model cannot be run with these values (out of bounds, a non-finite coefficient)."""


class StorageError(InputError):
    """A run file that cannot be created or written (path, permission, space, HDF5 failure).

    An input error: the fix (another folder, free space, a new file name) is the user's.
    """

    def __init__(self, message: str, *, path: str | Path | None = None) -> None:
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)
