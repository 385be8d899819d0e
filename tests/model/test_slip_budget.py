"""A model run that slips far more often than allowed is stopped with a clear error
(``Simulator.run(max_slips=...)``), and the workbench's fits count such a model as one that
cannot be run instead of integrating millions of chattering slips."""

from __future__ import annotations

import pytest

from rigctl.errors import SimulationError
from rigctl.model import Drive, Simulator, build_model
from rigctl.model.simulator import SlipBudgetError

DRIVE = Drive.constant(300.0, 1e-3, 10.0)  # about 300 slips at the paper's preset


def test_a_run_over_its_slip_budget_stops_with_an_error_naming_the_budget():
    sim = Simulator(build_model("paper"), 1024.0)
    with pytest.raises(SlipBudgetError, match=r"more than 100 global slips by t = "):
        sim.run(DRIVE, record_elements=False, max_slips=100)


def test_a_run_within_its_budget_is_the_unbounded_run():
    sim = Simulator(build_model("paper"), 1024.0)
    free = sim.run(DRIVE, record_elements=False)
    assert 200 < len(free.events) < 400
    bounded = sim.run(DRIVE, record_elements=False, max_slips=len(free.events))
    assert [e.t_start_s for e in bounded.events] == [e.t_start_s for e in free.events]
    assert (bounded.ft_N == free.ft_N).all()


def test_the_budget_error_is_a_simulation_error():
    assert issubclass(SlipBudgetError, SimulationError)
