"""The DAQ (force sensor and analog channels): sample blocks, the channel map, the abstract DAQ."""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from drivers.errors import DeviceStateError
from drivers.interfaces.common import Device, FloatArray, IntArray
from drivers.validate import check_argument, check_count, check_timeout

ForceAxis = Literal["fx", "fy", "fz"]


@dataclass(frozen=True, eq=False)
class DaqBlock:
    """Samples read in one call, in SI units.

    ``t_s`` is rebuilt from the unwrapped sample counter, ``t = (counter - counter_origin) /
    rate_hz`` with the origin at the first sample after ``start()`` (docs/protocols.md: never host
    arrival times). ``host_monotonic_ns`` is the host time the block's last sample arrived (block
    assembly time for an empty block): pairs of (last counter, host time) let the acquisition layer
    fit the device clock against the host clock. ``dropped_total`` counts samples lost so far
    (never invented).
    """

    counter: IntArray
    t_s: FloatArray
    fx_N: FloatArray
    fy_N: FloatArray
    fz_N: FloatArray
    ain_V: FloatArray
    host_monotonic_ns: int
    dropped_total: int
    rate_hz: float

    def __post_init__(self) -> None:
        n = self.counter.shape[0]
        if self.counter.ndim != 1 or self.counter.dtype != np.int64:
            raise ValueError("DaqBlock.counter must be a 1-D int64 array")
        for key in ("t_s", "fx_N", "fy_N", "fz_N"):
            arr = getattr(self, key)
            if arr.shape != (n,) or arr.dtype != np.float64:
                raise ValueError(f"DaqBlock.{key} must be float64 of shape ({n},), got {arr.shape}")
        if self.ain_V.shape != (n, 3) or self.ain_V.dtype != np.float64:
            raise ValueError(f"DaqBlock.ain_V must be float64 of shape ({n}, 3)")

    def __len__(self) -> int:
        return int(self.counter.shape[0])

    @classmethod
    def from_counts(
        cls,
        counter: IntArray,
        force_counts: NDArray[np.integer],
        ain_counts: NDArray[np.integer],
        *,
        force_N_per_count: float,
        volts_per_count: float,
        rate_hz: float,
        host_monotonic_ns: int,
        dropped_total: int,
        counter_origin: int = 0,
    ) -> DaqBlock:
        """Build a block from raw counts (n x 3 each) with the protocol's scales.

        ``t_s = (counter - counter_origin) / rate_hz`` (docs/protocols.md, "t = t0 + n / rate").
        """
        counter = np.asarray(counter, dtype=np.int64)
        forces = np.asarray(force_counts, dtype=np.float64).reshape(-1, 3) * force_N_per_count
        ain = np.asarray(ain_counts, dtype=np.float64).reshape(-1, 3) * volts_per_count
        return cls(
            counter=counter,
            t_s=(counter - counter_origin).astype(np.float64) / rate_hz,
            fx_N=np.ascontiguousarray(forces[:, 0]),
            fy_N=np.ascontiguousarray(forces[:, 1]),
            fz_N=np.ascontiguousarray(forces[:, 2]),
            ain_V=np.ascontiguousarray(ain),
            host_monotonic_ns=host_monotonic_ns,
            dropped_total=dropped_total,
            rate_hz=rate_hz,
        )

    @classmethod
    def empty(cls, *, rate_hz: float, host_monotonic_ns: int, dropped_total: int) -> DaqBlock:
        """A block with no samples (a read that timed out while streaming)."""
        none = np.zeros(0, dtype=np.int64)
        return cls.from_counts(
            none,
            np.zeros((0, 3), dtype=np.int64),
            np.zeros((0, 3), dtype=np.int64),
            force_N_per_count=1.0,
            volts_per_count=1.0,
            rate_hz=rate_hz,
            host_monotonic_ns=host_monotonic_ns,
            dropped_total=dropped_total,
        )


@dataclass(frozen=True)
class ChannelMap:
    """Which sensor axis is Ft / Fn (with sign) and which analog channel is D1 / D2 (with scale).

    ``ft_N = ft_sign * f<ft_axis>_N``, likewise Fn; ``d1_m = d1_m_per_V * ain_V[:, d1_channel]``.
    Default probe scale 7.4e-6 m/V: 74 um over 10 V (docs/protocols.md).
    """

    ft_axis: ForceAxis = "fx"
    ft_sign: int = 1
    fn_axis: ForceAxis = "fz"
    fn_sign: int = 1
    d1_channel: int = 0
    d1_m_per_V: float = 7.4e-6
    d2_channel: int = 1
    d2_m_per_V: float = 7.4e-6
    probe_rail_V: float = 9.99
    """A probe's analog output at or beyond this many volts is over range (it sits at the rail)."""

    def __post_init__(self) -> None:
        for key in ("ft_axis", "fn_axis"):
            axis = getattr(self, key)
            if axis not in ("fx", "fy", "fz"):
                raise ValueError(f"ChannelMap.{key} must be 'fx', 'fy' or 'fz', got {axis!r}")
        if self.ft_axis == self.fn_axis:
            raise ValueError(f"ChannelMap: Ft and Fn cannot both be {self.ft_axis}")
        for key in ("ft_sign", "fn_sign"):
            if getattr(self, key) not in (1, -1) or isinstance(getattr(self, key), bool):
                raise ValueError(f"ChannelMap.{key} must be +1 or -1, got {getattr(self, key)!r}")
        for key in ("d1_channel", "d2_channel"):
            value = getattr(self, key)
            if isinstance(value, bool) or value not in (0, 1, 2):
                raise ValueError(f"ChannelMap.{key} must be 0, 1 or 2, got {value!r}")
        for key in ("d1_m_per_V", "d2_m_per_V"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"ChannelMap.{key} must be a number, got {value!r}")
            if not (math.isfinite(value) and value != 0):
                raise ValueError(f"ChannelMap.{key} must be finite and non-zero, got {value!r}")

    def ft_N(self, block: DaqBlock) -> FloatArray:
        """Tangential (friction) force [N]."""
        return float(self.ft_sign) * getattr(block, f"{self.ft_axis}_N")

    def fn_N(self, block: DaqBlock) -> FloatArray:
        """Normal force [N]."""
        return float(self.fn_sign) * getattr(block, f"{self.fn_axis}_N")

    def d1_m(self, block: DaqBlock) -> FloatArray:
        """Displacement probe 1 [m] from its analog output."""
        return self.d1_m_per_V * block.ain_V[:, self.d1_channel]

    def d2_m(self, block: DaqBlock) -> FloatArray:
        """Displacement probe 2 [m] from its analog output."""
        return self.d2_m_per_V * block.ain_V[:, self.d2_channel]

    def probe_over_range(self, block: DaqBlock) -> dict[str, np.ndarray]:
        """Per probe (``d1_m``, ``d2_m``), the samples whose analog output sits at the rail."""
        return {
            "d1_m": np.abs(block.ain_V[:, self.d1_channel]) >= self.probe_rail_V,
            "d2_m": np.abs(block.ain_V[:, self.d2_channel]) >= self.probe_rail_V,
        }


class Daq(Device):
    """Synchronous sampling of Fx, Fy, Fz and three analog inputs at ``rate_hz``. Usage::

        daq.start()
        block = daq.read_block(1024, timeout_s=1.0)    # up to 1024 samples (one second at 1024 Hz)
        fn_N = daq.channel_map.fn_N(block)             # forces and probes through the channel map
        daq.stop()
    """

    DEFAULT_RATE_HZ = 1024.0

    def __init__(
        self,
        name: str,
        rate_hz: float = DEFAULT_RATE_HZ,
        channel_map: ChannelMap | None = None,
    ) -> None:
        super().__init__(name)
        rate = check_argument(name, "rate_hz", rate_hz, gt=0.0)
        self._rate_hz = rate
        self._channel_map = channel_map if channel_map is not None else ChannelMap()
        self._streaming = False

    @property
    def rate_hz(self) -> float:
        """Sample rate [Hz]."""
        return self._rate_hz

    @property
    def channel_map(self) -> ChannelMap:
        """How Fx/Fy/Fz and ain0..2 map onto Ft, Fn, D1, D2."""
        return self._channel_map

    @property
    def streaming(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._streaming

    def start(self) -> None:
        """Start streaming samples."""
        self._check_open()
        self._do_start()
        self._streaming = True

    def stop(self) -> None:
        """Stop streaming (samples already received stay readable)."""
        self._check_open()
        self._do_stop()
        self._streaming = False

    def tare(self) -> None:
        """Zero the forces at the current reading."""
        self._check_open()
        self._do_tare()

    def set_rate(self, rate_hz: float) -> None:
        """Change the sample rate (only while stopped: sample times depend on it)."""
        self._check_open()
        rate = check_argument(self.name, "rate_hz", rate_hz, gt=0.0)
        if self._streaming:
            raise DeviceStateError(self.name, "set_rate refused while streaming: stop() first")
        self._do_set_rate(rate)
        self._rate_hz = rate

    def read_block(self, max_samples: int, timeout_s: float) -> DaqBlock:
        """Up to ``max_samples`` complete samples, waiting at most ``timeout_s`` for the first.

        Returns an empty block if none came in time while streaming.
        """
        self._check_open()
        count = check_count(self.name, "max_samples", max_samples)
        wait_s = check_timeout(self.name, timeout_s)
        return self._do_read_block(count, wait_s)

    @property
    @abstractmethod
    def force_range_N(self) -> float:
        """The force sensor's range [N]: a force reading of this size (or more) is saturated, so it
        means "at least this much". The force guard trips there and the dry run refuses a target
        above it. A real sensor's comes from the configuration, a simulated one's from its
        settings; either is at most the converter's full scale."""

    @property
    @abstractmethod
    def dropped_samples(self) -> int:
        """Samples lost so far (counter gaps, incomplete pairs, overflow), never invented."""

    @property
    @abstractmethod
    def protocol_errors(self) -> int:
        """Malformed frames received so far (counted and skipped)."""

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_tare(self) -> None: ...

    @abstractmethod
    def _do_set_rate(self, rate_hz: float) -> None: ...

    @abstractmethod
    def _do_read_block(self, max_samples: int, timeout_s: float) -> DaqBlock: ...
