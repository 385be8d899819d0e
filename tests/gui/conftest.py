"""Fixtures shared by the GUI tests."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from rigctl.config.loader import default_config
from rigctl.rigs import OpenRig, open_rig


@pytest.fixture
def rig() -> Iterator[OpenRig]:
    """A simulated rig at ``--speed max``; its emergency stops are released after the test (a test
    that presses F12 leaves them latched)."""
    with open_rig("sim", default_config(), speed=math.inf) as r:
        yield r
        for stage in (r.devices.tangential_stage, r.devices.normal_stage):
            stage.emergency_stop_registry.reset()
