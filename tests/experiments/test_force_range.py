"""The force sensor's range bounds what a protocol may ask and what the guard sees (issue 35 item 1).

Before: the simulated sensor saturated at 655.34 N (0.02 N/count) while the guard's limit was 800 N, so
``rigctl run nlre --param peak_N=700 ...`` pressed on a reading stuck at 655.3 N until the stage's own
over-load alarm at 800 N; the dry run accepted it. Now the default sensor reads past the rated 800 N
(0.025 N/count: 819.175 N), and a limit above the range is refused before anything moves.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from drivers.ratings import RATED_NORMAL_FORCE_N
from experiments.context import RigLimits
from experiments.errors import PlanError
from experiments.normal_load import LoadNormal
from experiments.runner import Runner, dry_run, get_protocol
from experiments.steps import PlanState
from rigctl.cli.main import main
from rigctl.config import adapters
from rigctl.config.errors import ConfigError
from rigctl.config.loader import default_config, parse_config
from rigctl.model import build_model
from rigctl.rigs import open_rig, rig_limits
from rigctl.storage.reader import read_run

DEFAULT_RANGE_N = 819.175  # the default sensor: 32767 counts x 0.025 N/count
OLD_RANGE_N = 32767 * 0.02  # the sensor of the issue: 655.34 N at 0.02 N/count


def _plan(protocol: str, params: dict[str, str], limits: RigLimits) -> None:
    dry_run(get_protocol(protocol), params, limits, 0.0)


def test_the_default_sensor_reads_the_rated_load() -> None:
    limits = rig_limits(default_config())
    assert limits.force_range_N == DEFAULT_RANGE_N >= RATED_NORMAL_FORCE_N == limits.max_force_N
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        assert rig.devices.daq.force_range_N == pytest.approx(DEFAULT_RANGE_N, rel=1e-12)
    _plan("nlre", {"peak_N": "700", "repetitions": "1", "interval_s": "1"}, limits)  # the run


@pytest.mark.parametrize(
    ("config_text", "limit", "range_"),
    [
        ("[daq]\nforce_N_per_count = 0.02\n", "800 N", "655.34 N"),  # the sensor
        ("[daq]\nforce_range_N = 650\n[normal_stage.limits]\nmax_force_N = 700\n", "700 N", "650 N"),
        ("[daq]\nforce_range_N = 350\n", "800 N", "350 N"),
    ],
)
def test_the_configuration_refuses_a_limit_above_the_sensor_range_naming_both(
        config_text: str, limit: str, range_: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_config(config_text)
    text = str(info.value)
    assert info.value.key == "normal_stage.limits.max_force_N"
    assert f"{limit} is above the force sensor's range {range_}" in text, text
    assert "daq.force_range_N" in text and "daq.force_N_per_count" in text and "\n" not in text


def test_the_command_line_refuses_it_before_the_rig_opens(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "small_sensor.toml"
    cfg.write_text("[daq]\nforce_N_per_count = 0.02\n")
    assert main(["run", "nlre", "--dry-run", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "max_force_N: 800 N" in err and "655.34 N" in err, err


def test_the_dry_run_refuses_a_limit_above_the_sensor_range_naming_both() -> None:
    """Limits the configuration did not check (a runner's DAQ reading less than configured)."""
    limits = replace(rig_limits(default_config()), force_range_N=OLD_RANGE_N)
    with pytest.raises(PlanError) as info:
        _plan("tlre", {"fn_N": "300"}, limits)  # its targets (360 N) are within the range
    text = str(info.value)
    assert "limit 800 N (normal_stage.limits.max_force_N)" in text, text
    assert "range 655.34 N (daq.force_range_N)" in text and "\n" not in text, text
    _plan("tlre", {"fn_N": "300"}, replace(limits, max_force_N=OLD_RANGE_N))  # at the range: fine


def test_a_load_step_refuses_a_target_above_the_range_naming_both() -> None:
    """The step's own check, for limits that were never checked against the range."""
    limits = replace(rig_limits(default_config()), force_range_N=OLD_RANGE_N)
    with pytest.raises(PlanError, match=r"700 N is above the force sensor's range 655\.34 N"):
        LoadNormal(700.0).plan(PlanState(x_m=0.0, x_start_m=0.0), limits)


def test_the_limit_in_effect_is_never_above_the_open_daq_range() -> None:
    config = parse_config("[daq]\nforce_N_per_count = 0.02\n[normal_stage.limits]\nmax_force_N = 650\n")
    with open_rig("sim", config, speed=math.inf) as rig:
        assert rig.devices.daq.force_range_N == OLD_RANGE_N  # the simulated sensor's settings
        limits = replace(rig.limits, force_range_N=math.inf, max_force_N=800.0)  # unchecked limits
        runner = Runner(get_protocol("nlre"), {"peak_N": "600", "repetitions": "1"}, rig.devices,
                        limits, out=None)
        assert runner.limits.force_range_N == OLD_RANGE_N
        with pytest.raises(PlanError, match=r"limit 800 N .* above the force sensor's range 655\.34 N"):
            runner.plan()


def test_a_load_that_passes_the_sensor_range_mid_run_trips_the_guard_on_saturation(tmp_path: Path) -> None:
    """Normal coupling (kappa 0.5) raises Fn with Ft during the slide: from 150 N to about 165 N, past
    a sensor saturating at 155.6 N (0.00475 N/count) though the plan (150 N) was within it. The limit
    is the range itself (a larger one is refused): the guard trips on the saturated reading and the
    load is released."""
    range_N = 32767 * 0.00475
    with pytest.raises(ConfigError, match=r"800 N is above the force sensor's range 155\.643 N"):
        parse_config("[daq]\nforce_N_per_count = 0.00475\n")
    config = parse_config(f"[daq]\nforce_N_per_count = 0.00475\n"
                          f"[normal_stage.limits]\nmax_force_N = {range_N!r}\n")
    model = build_model("paper", effects=["normal_coupling"],
                        effect_params={"normal_coupling": {"kappa": 0.5}})
    out = tmp_path / "saturated.h5"
    params = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1", "fn_N": "150", "preload_factor": "1.0"}
    with open_rig("sim", config, speed=math.inf, model=model) as rig:
        assert rig.devices.daq.force_range_N == range_N == pytest.approx(155.6, abs=0.1)
        outcome = Runner(
            get_protocol("tlre"), params, rig.devices, rig.limits, out=out,
            daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
            on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s),
        ).run()
        assert outcome.status == "failed"
        assert outcome.error is not None
        assert "ForceLimitError" in outcome.error and "saturated" in outcome.error, outcome.error
        assert "155.6" in outcome.error
        assert not rig.devices.tangential_stage.status().moving
        assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # released after the trip
    run = read_run(out)
    assert run.fn_N.max() == pytest.approx(range_N)  # the record shows the saturated reading
