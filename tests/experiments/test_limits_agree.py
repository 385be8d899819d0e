"""The dry run and the stage driver check a move against the same limits with the same code.

For a table of tangential moves, the dry run (``MoveTangential.plan`` against the configured
:class:`~experiments.context.RigLimits`) and the simulated rig's tangential stage driver (built from
the same configuration, ``move_absolute``) refuse exactly the same moves, and the dry run's refusal
is the driver's message behind the step's name.
"""

from __future__ import annotations

import math

import pytest

from drivers.errors import InvalidValueError
from experiments.errors import PlanError
from experiments.steps import MoveTangential, PlanState, ReturnTangential
from rigctl.config.adapters import sim_settings
from rigctl.config.loader import default_config
from rigctl.rigs import rig_limits
from sim_devices.backends import open_sim_rig

CONFIG = default_config()
LIMITS = rig_limits(CONFIG)
V_MAX = LIMITS.tangential.max_velocity_m_s

MOVES = [  # (distance from the start [m], velocity [m/s])
    (10e-6, 1e-5),
    (0.0, 1e-5),
    (-1e-3, V_MAX),  # at the speed limit: allowed
    (0.101, 1e-5),  # beyond the maximum travel
    (-0.1001, 1e-5),  # below the minimum travel
    (1e-3, 1.01 * V_MAX),  # above the speed limit
    (1e-3, 0.0),
    (1e-3, -1e-5),
    (1e-3, math.nan),
    (1e-3, math.inf),
    (math.nan, 1e-5),
    (0.2, 10 * V_MAX),  # both beyond: the same one is named
]


def dry_run_refusal(start_m: float, distance_m: float, velocity_m_s: float) -> str | None:
    step = MoveTangential(distance_m, velocity_m_s)
    try:
        step.plan(PlanState(x_m=start_m, x_start_m=start_m), LIMITS)
    except PlanError as exc:
        prefix = f"step '{step.describe()}': "
        assert str(exc).startswith(prefix)
        return str(exc).removeprefix(prefix)
    return None


def test_dry_run_and_driver_refuse_the_same_moves_with_the_same_message() -> None:
    with open_sim_rig("sim", settings=sim_settings(CONFIG), speed=None) as sim:
        stage = sim.devices.tangential_stage
        assert stage.limits == LIMITS.tangential
        stage.enable()
        start = stage.position_m()
        refused = 0
        for distance, velocity in MOVES:
            planned = dry_run_refusal(start, distance, velocity)
            try:
                stage.move_absolute(start + distance, velocity)
                driven = None
                stage.stop()
            except InvalidValueError as exc:
                driven = str(exc)
            assert planned == driven, (distance, velocity)
            refused += driven is not None
        assert refused == len(MOVES) - 3


@pytest.mark.parametrize("velocity", [0.0, 1.01 * V_MAX, math.nan])
def test_returns_use_the_same_velocity_check(velocity: float) -> None:
    step = ReturnTangential(velocity)
    with pytest.raises(PlanError) as info:
        step.plan(PlanState(x_m=0.1, x_start_m=0.09), LIMITS)
    with pytest.raises(InvalidValueError) as driver:
        LIMITS.tangential.check_move("tangential", 0.09, velocity)
    assert str(info.value) == f"step '{step.describe()}': {driver.value}"
