"""The force sensor's range bounds what a protocol may ask and what the guard sees (issue 35 item 1).

Before: the simulated sensor saturates at 655.34 N while the guard's limit is 800 N, so
``rigctl run nlre --param peak_N=700 ...`` pressed on a reading stuck at 655.3 N until the stage's own
over-load alarm at 800 N; the dry run accepted it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from experiments.errors import PlanError
from experiments.runner import Runner, dry_run, get_protocol
from rigctl.config import adapters
from rigctl.config.loader import default_config, parse_config
from rigctl.model import build_model
from rigctl.rigs import open_rig, rig_limits
from rigctl.storage.reader import read_run

SIM_RANGE_N = 32767 * 0.02  # the simulated sensor's int16 full scale at 0.02 N/count


def _plan(protocol: str, params: dict[str, str], config_text: str = "") -> None:
    dry_run(get_protocol(protocol), params, rig_limits(parse_config(config_text)), 0.0)


@pytest.mark.parametrize(
    ("config_text", "params"),
    [
        ("", {"peak_N": "700"}),  # the case: below the 800 N limit, above the range
        ("[normal_stage.limits]\nmax_force_N = 700\n", {"peak_N": "680"}),
    ],
)
def test_the_dry_run_refuses_a_peak_above_the_sensor_range_naming_both(config_text, params) -> None:
    with pytest.raises(PlanError) as info:
        _plan("nlre", {**params, "repetitions": "1", "interval_s": "1"}, config_text)
    text = str(info.value)
    assert f"{params['peak_N']} N" in text and "655.34 N" in text and "range" in text, text


def test_a_configured_sensor_range_bounds_the_plan() -> None:
    _plan("tlre", {"fn_N": "300"})  # pre-load 360 N: within 655.34 N
    with pytest.raises(PlanError, match=r"pre-load 360 N.*360 N is above the force sensor's range 350 N"):
        _plan("tlre", {"fn_N": "300"}, "[daq]\nforce_range_N = 350\n")


def test_the_limit_in_effect_is_never_above_the_open_daq_range() -> None:
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        assert rig.devices.daq.force_range_N == SIM_RANGE_N  # the simulated sensor's settings
        limits = replace(rig.limits, force_range_N=math.inf)  # limits that know no range
        runner = Runner(get_protocol("nlre"), {"peak_N": "700", "repetitions": "1"}, rig.devices,
                        limits, out=None)
        assert runner.limits.force_range_N == SIM_RANGE_N
        with pytest.raises(PlanError, match=r"700 N is above the force sensor's range 655\.34 N"):
            runner.plan()


def test_a_load_that_passes_the_sensor_range_mid_run_trips_the_guard_on_saturation(tmp_path: Path) -> None:
    """Normal coupling (kappa 0.5) raises Fn with Ft during the slide: from 150 N to about 165 N, past
    a sensor saturating at 155.6 N (0.00475 N/count) though the plan (150 N) was within it and the
    limit is 800 N. The guard trips on the saturated reading and the load is released."""
    config = parse_config("[daq]\nforce_N_per_count = 0.00475\n")
    model = build_model("paper", effects=["normal_coupling"],
                        effect_params={"normal_coupling": {"kappa": 0.5}})
    out = tmp_path / "saturated.h5"
    params = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1", "fn_N": "150", "preload_factor": "1.0"}
    with open_rig("sim", config, speed=math.inf, model=model) as rig:
        range_N = rig.devices.daq.force_range_N
        assert range_N == pytest.approx(155.6, abs=0.1)
        outcome = Runner(
            get_protocol("tlre"), params, rig.devices, rig.limits, out=out,
            daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
            on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s),
        ).run()
        assert outcome.status == "failed"
        assert "ForceLimitError" in outcome.error and "saturated" in outcome.error, outcome.error
        assert "155.6" in outcome.error and "800 N" in outcome.error
        assert not rig.devices.tangential_stage.status().moving
        assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # released after the trip
    run = read_run(out)
    assert run.fn_N.max() == pytest.approx(range_N)  # the record shows the saturated reading
