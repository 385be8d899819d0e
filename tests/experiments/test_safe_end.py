"""Every protocol ends in the safe state, whatever its steps (issue 35, item 6).

A protocol (here as a protocol file would write it) that loads the contact and never releases it
completes with the normal load released after its last step, recorded as such (marker
``safe_state`` before ``end``) and said in the plan; one that releases it is not moved again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from experiments.normal_load import LoadNormal, ReleaseNormal
from experiments.protocols import Protocol, param
from experiments.runner import Runner, dry_run
from experiments.steps import Hold, Step
from rigctl.config import adapters
from rigctl.config.loader import default_config
from rigctl.rigs import open_rig
from rigctl.storage.reader import RunReader


@dataclass(frozen=True)
class _Params:
    fn_N: float = param(300.0, "N", "normal force")
    release: int = param(0, "-", "1: end with a release of the normal load")


def _build(p: _Params) -> list[Step]:
    steps: list[Step] = [LoadNormal(p.fn_N), Hold(0.5, "hold")]
    return [*steps, ReleaseNormal()] if p.release else steps


LEAVES_LOADED = Protocol("leaves_loaded", "load, hold, no release", _Params, _build)


@pytest.fixture
def rig():
    with open_rig("sim", default_config(), speed=math.inf) as r:
        yield r


def _run(rig, params: dict, out):
    runner = Runner(LEAVES_LOADED, params, rig.devices, rig.limits, out=out,
                    daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
                    on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s))
    return runner.run()


def test_a_protocol_that_never_releases_the_load_ends_released_and_recorded(rig, tmp_path):
    out = tmp_path / "loaded.h5"
    outcome = _run(rig, {}, out)
    assert outcome.status == "completed", outcome.error
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # the rig is not left loaded
    assert not rig.devices.tangential_stage.status().moving
    with RunReader(out) as r:
        events = [e for e in r.events() if not e.name.startswith("probe_")]
        d = r.read_daq()
        assert r.status == "completed"
    names = [e.name for e in events]
    assert names[-2:] == ["safe_state", "end"], names  # the release after the last step, then end
    assert "left the normal load on" in events[-2].message and "(Fn 29" in events[-2].message
    assert d["fn_N"].max() > 290.0 and abs(float(d["fn_N"][-20:].mean())) < 1.0


@pytest.mark.slow
def test_a_protocol_that_releases_the_load_is_not_moved_again(rig, tmp_path):
    out = tmp_path / "released.h5"
    outcome = _run(rig, {"release": "1"}, out)
    assert outcome.status == "completed", outcome.error
    z_released = rig.devices.normal_stage.position_m()
    with RunReader(out) as r:
        events = [e for e in r.events() if not e.name.startswith("probe_")]
    assert [e.name for e in events][-3:] == ["released", "safe_state", "end"]
    assert "already released" in events[-2].message
    assert rig.devices.normal_stage.position_m() == pytest.approx(z_released, abs=1e-9)


def test_the_plan_says_the_safe_state_releases_a_load_left_on(rig):
    x0 = rig.devices.tangential_stage.position_m()
    loaded, _ = dry_run(LEAVES_LOADED, {}, rig.limits, x0)
    released, _ = dry_run(LEAVES_LOADED, {"release": "1"}, rig.limits, x0)
    assert loaded.ends_loaded_N == 300.0 and released.ends_loaded_N == 0.0
    assert "then the safe state: the last step leaves Fn 300 N on" in loaded.summary()
    assert "safe state" not in released.summary()
