"""Acquisition: the DAQ stream, the camera and the stage positions recorded concurrently into a run
file on one clock, with live subscribers and every drop counted (docs/acquisition.md)."""

from __future__ import annotations

from rigctl.acquisition.clockmap import ClockMap
from rigctl.acquisition.publisher import Publisher, Subscription
from rigctl.acquisition.session import Acquisition, AcquisitionStats, RigDevices

__all__ = ["Acquisition", "AcquisitionStats", "ClockMap", "Publisher", "RigDevices", "Subscription"]
