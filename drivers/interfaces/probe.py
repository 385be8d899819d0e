"""Displacement probes: streamed samples and the abstract probe."""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import NamedTuple

from drivers.errors import DeviceStateError, LimitError, NotSupportedError
from drivers.interfaces.common import Device, FloatArray, IntArray
from drivers.validate import check_argument, check_count, check_timeout


class ProbeSamples(NamedTuple):
    """Streamed probe samples: device sequence numbers, values [m], host arrival times [ns].

    An over-range sample is ``+inf`` (above the range) or ``-inf`` (below): flagged, never clipped,
    and its direction kept; ``~np.isfinite(values_m)`` is the over-range mask.
    """

    seq: IntArray
    values_m: FloatArray
    host_ns: IntArray


class DisplacementProbe(Device):
    """A displacement probe read one value at a time or as a stream.

    A single reading beyond the range raises :class:`~drivers.errors.OverRangeError`; a streamed one
    is ``+-inf`` (see :class:`ProbeSamples`). Usage::

        probe.zero()                                   # the current position reads 0 from now on
        d_m = probe.read_m()
        probe.start_stream(1000.0)
        samples = probe.read_stream(1000, timeout_s=1.0)   # seq, values_m, host_ns
        probe.stop_stream()
        probe.move_mount(30e-6)     # a motorised mount: the readings drop by 30 um from now on

    A probe's range is fixed about its stand-off: :meth:`zero` re-references the reading, only
    moving the probe (:meth:`move_mount`) brings a target that left the range back into it.
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._streaming = False
        self._mount_m = 0.0

    @property
    @abstractmethod
    def range_m(self) -> float:
        """Full measuring range [m], centred on the zero."""

    @property
    @abstractmethod
    def resolution_m(self) -> float:
        """Resolution (quantisation step) [m]."""

    @property
    def streaming(self) -> bool:
        """True between :meth:`start_stream` and :meth:`stop_stream`."""
        return self._streaming

    def zero(self) -> None:
        """Make the current position the zero."""
        self._check_idle("zero")
        self._do_zero()

    def read_m(self) -> float:
        """One displacement reading [m] relative to the zero; OverRangeError beyond the range."""
        self._check_idle("read_m")
        return self._do_read_m()

    def start_stream(self, rate_hz: float) -> None:
        """Start streaming at ``rate_hz``."""
        self._check_idle("start_stream")
        rate = check_argument(self.name, "rate_hz", rate_hz, gt=0.0)
        self._do_start_stream(rate)
        self._streaming = True

    def read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples:
        """Up to ``max_samples`` streamed samples, waiting at most ``timeout_s`` for the first."""
        self._check_open()
        count = check_count(self.name, "max_samples", max_samples)
        wait_s = check_timeout(self.name, timeout_s)
        return self._do_read_stream(count, wait_s)

    def stop_stream(self) -> None:
        """Stop streaming (samples already received stay readable)."""
        self._check_open()
        self._do_stop_stream()
        self._streaming = False

    @property
    def mount_travel_m(self) -> float:
        """Travel of the probe's motorised mount, centred on where it started [m]; 0 (the default)
        for a manual mount, which :meth:`move_mount` refuses."""
        return 0.0

    @property
    def mount_speed_m_s(self) -> float:
        """Speed of the motorised mount [m/s]: a move of ``m`` takes ``|m| / mount_speed_m_s`` from
        its command, during which the readings change by the part of the move made. ``inf`` (the
        default) for a manual mount."""
        return math.inf

    @property
    def mount_m(self) -> float:
        """Where the mount is, from where it started [m] (the sum of the moves made)."""
        return self._mount_m

    def move_mount(self, distance_m: float) -> None:
        """Move the probe towards its target by ``distance_m`` (negative: away), at
        :attr:`mount_speed_m_s` from the command on: every reading after the move is ``distance_m``
        lower. A move beyond the mount's travel raises LimitError and
        nothing moves; a manual mount raises NotSupportedError."""
        self._check_idle("move_mount")
        d = check_argument(self.name, "distance_m", distance_m, unit="m")
        half = 0.5 * self.mount_travel_m
        if half <= 0:
            raise NotSupportedError(self.name, "move_mount (the probe's mount is manual)")
        target = self._mount_m + d
        if abs(target) > half:
            raise LimitError(self.name, "mount_m", target, half if target > 0 else -half, "m")
        self._do_move_mount(d)
        self._mount_m = target

    def _do_move_mount(self, distance_m: float) -> None:
        raise NotSupportedError(self.name, "move_mount")

    def _check_idle(self, command: str) -> None:
        self._check_open()
        if self._streaming:
            raise DeviceStateError(self.name, f"{command} refused while streaming: stop_stream() first")

    @abstractmethod
    def _do_zero(self) -> None: ...

    @abstractmethod
    def _do_read_m(self) -> float: ...

    @abstractmethod
    def _do_start_stream(self, rate_hz: float) -> None: ...

    @abstractmethod
    def _do_read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples: ...

    @abstractmethod
    def _do_stop_stream(self) -> None: ...
