"""Fixtures of the simulated-device tests: every rig, server, bus, pty and thread is stopped in teardown."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from drivers.safety import EmergencyStop
from sim_devices.backends import SimRig, open_sim_rig

SPEED = 20.0
"""Clock factor of the accelerated rigs used by the behavioural tests."""


@pytest.fixture
def estop() -> EmergencyStop:
    """A private emergency-stop registry (the process-wide one is left alone)."""
    return EmergencyStop()


@pytest.fixture(params=["sim", "sim-wire"])
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def sim(backend: str, estop: EmergencyStop) -> Iterator[SimRig]:
    """A whole simulated rig, accelerated, with the backend under test."""
    with open_sim_rig(backend, speed=SPEED, emergency_stop=estop) as rig:
        yield rig
