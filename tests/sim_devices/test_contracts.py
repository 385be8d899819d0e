"""The same behavioural tests against both simulated backends (python-microscope style).

Each class runs the drivers' interface contract (tests/drivers/contract.py) and the simulated rig's
physical contract (sim_contract.py) twice: on the in-process backend (``sim``) and on the wire-level
simulators behind the real drivers (``sim-wire``).
"""

from __future__ import annotations

import pytest

from drivers.interfaces import Camera, Daq, DisplacementProbe, LoadingStage
from sim_devices.backends import SimRig
from tests.drivers.contract import CameraContract, DaqContract, ProbeContract, StageContract

from .sim_contract import SimCameraContract, SimDaqContract, SimProbeContract, SimStageContract


class TestTangentialStage(StageContract, SimStageContract):
    stage_key = "tangential_stage"
    direction = 1.0

    @pytest.fixture
    def stage(self, sim: SimRig) -> LoadingStage:
        return sim.devices.tangential_stage


class TestNormalStage(StageContract, SimStageContract):
    stage_key = "normal_stage"
    direction = -1.0  # away from the contact

    @pytest.fixture
    def stage(self, sim: SimRig) -> LoadingStage:
        return sim.devices.normal_stage


class TestDaq(DaqContract, SimDaqContract):
    @pytest.fixture
    def daq(self, sim: SimRig) -> Daq:
        return sim.devices.daq


class TestProbeD1(ProbeContract, SimProbeContract):
    probe_index = 0

    @pytest.fixture
    def probe(self, sim: SimRig) -> DisplacementProbe:
        return sim.devices.d1


class TestProbeD2(ProbeContract, SimProbeContract):
    probe_index = 1

    @pytest.fixture
    def probe(self, sim: SimRig) -> DisplacementProbe:
        return sim.devices.d2


class TestCamera(CameraContract, SimCameraContract):
    @pytest.fixture
    def camera(self, sim: SimRig) -> Camera:
        return sim.devices.camera
