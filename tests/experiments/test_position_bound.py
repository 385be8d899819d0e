"""The normal stage's position bound backs up the force reading (issue 35 item 1).

A reading that plateaus below the range the configuration knows (the sensor's amplifier saturated by
a mis-set gain: frozen at its limit but for its live noise, so neither the force guard, which trips
at the configured range, nor the stale-reading watchdog can see it) must not let the load step press
on until the stage's own over-load: it stops where ``max_approach_m`` puts it past the first contact
reading.
"""

from __future__ import annotations

import math
import re
import threading
import time
from dataclasses import replace
from pathlib import Path

import pytest

from experiments.runner import Runner, get_protocol
from rigctl.config import adapters
from rigctl.config.loader import parse_config
from rigctl.rigs import open_rig
from rigctl.storage.reader import read_run

PLATEAU_N = 300.0  # the amplifier's limit: below the TLRE's 360 N pre-load
MAX_APPROACH_M = 85e-6  # the deflection at the 500 N limit (80 um) with a margin
TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5", "preload_hold_s": "1",
        "settle_s": "1"}


def test_a_reading_that_plateaus_below_the_target_is_stopped_by_the_approach_bound(
        tmp_path: Path) -> None:
    config = parse_config(f"[normal_stage.limits]\nmax_force_N = 500\nmax_approach_m = {MAX_APPROACH_M}\n")
    out = tmp_path / "plateau.h5"
    with open_rig("sim", config, speed=math.inf) as rig:
        sensor = rig.sim.devices.daq.signals.sensor  # type: ignore[attr-defined]
        sensor.spec = replace(sensor.spec, amplifier_limit_N=PLATEAU_N)
        assert rig.devices.daq.force_range_N > 800.0  # the DAQ knows nothing of the amplifier
        runner = Runner(get_protocol("tlre"), TLRE, rig.devices, rig.limits, out=out,
                        daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
                        on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s))
        result: list = []
        th = threading.Thread(target=lambda: result.append(runner.run()))
        th.start()
        fn_max = z_max = 0.0
        alarm = False
        while th.is_alive():
            fn_max = max(fn_max, rig.sim.rig.state.fn_N)
            z_max = max(z_max, rig.devices.normal_stage.position_m())
            alarm = alarm or rig.devices.normal_stage.status().alarm_code == 3
            time.sleep(0.005)
        th.join(timeout=60)
        contact = rig.sim.rig.config.contact
        fn_end = rig.sim.rig.state.fn_N
    outcome = result[0]
    assert outcome.status == "failed"
    assert outcome.error is not None and "max_approach_m = 85 um" in outcome.error, outcome.error
    # the right place: no further than max_approach_m past the first contact reading
    found = re.search(r"first read a contact \(z = ([0-9.]+) mm", outcome.error)
    assert found, outcome.error
    z_first_contact_m = float(found.group(1)) * 1e-3
    assert z_max <= z_first_contact_m + MAX_APPROACH_M + 1e-7
    # which is at most one contact-search step (20 um) past the true contact: the load it leaves
    assert z_first_contact_m - contact.z_contact_m <= 20e-6 + 1e-7
    assert fn_max <= contact.fn_N(contact.z_contact_m + 20e-6 + MAX_APPROACH_M + 1e-7)
    assert fn_max > 360.0  # it did press past the plateau, on a reading that could not show it
    assert not alarm and fn_max < 800.0, fn_max  # stopped before the stage's over-load
    assert fn_end == pytest.approx(0.0, abs=0.05)  # the safe state released the load
    run = read_run(out)
    assert run.fn_N.max() < PLATEAU_N + 1.0  # what the record saw: the plateau
