"""Fixtures shared by the driver tests: every server, peer and thread is stopped in teardown."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from drivers.safety import EmergencyStop

from .drv_modbus_peer import ModbusPeer


@pytest.fixture
def estop() -> EmergencyStop:
    """A private emergency-stop registry (the process-wide one is left alone)."""
    return EmergencyStop()


@pytest.fixture
def peer() -> Iterator[ModbusPeer]:
    server = ModbusPeer()
    yield server
    server.close()
