"""Fixtures shared by the GUI tests."""

from __future__ import annotations

import gc
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


@pytest.fixture(autouse=True)
def _collect_after_each_test() -> Iterator[None]:
    """Reference cycles of a test's Qt objects are collected when the test ends, in the main thread
    with its run threads gone, not by a collection that happens to start inside a later test while
    that test's run thread works (one clean-clone run crashed in such a collection)."""
    yield
    gc.collect()
