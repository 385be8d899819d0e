"""What every device shares: a name used in every error, idempotent ``close()``, array types."""

from __future__ import annotations

from abc import ABC
from types import TracebackType
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from drivers.errors import DeviceStateError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
T = TypeVar("T")


class Device(ABC):  # noqa: B024 - an ABC for shared naming/closing; abstract hooks live below
    """Shared by every device: a name (used in every error) and idempotent ``close()``."""

    def __init__(self, name: str) -> None:
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"a device needs a non-empty name, got {name!r}")
        self._name = name
        self._closed = False

    @property
    def name(self) -> str:
        """The device name used in errors and logs (e.g. ``"normal_stage"``)."""
        return self._name

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def close(self) -> None:
        """Release the connection; a second call does nothing."""
        if not self._closed:
            self._closed = True
            self._do_close()

    def _do_close(self) -> None:  # noqa: B027 - optional hook
        """Hook: release the transport. Default: nothing to release."""

    def _check_open(self) -> None:
        if self._closed:
            raise DeviceStateError(self._name, "closed")

    def __enter__(self: T) -> T:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
