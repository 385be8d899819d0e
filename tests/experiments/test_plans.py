"""Dry runs: every protocol plans within the limits; violations are refused naming step and limit."""

from __future__ import annotations

import pytest

from experiments.errors import PlanError
from experiments.protocols import PROTOCOLS
from experiments.runner import dry_run, get_protocol
from rigctl.config.loader import default_config
from rigctl.rigs import rig_limits

LIMITS = rig_limits(default_config())
X0 = 0.1  # the simulated tangential stage starts mid-stroke


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_default_protocols_plan_within_limits(name):
    plan, steps = dry_run(PROTOCOLS[name], {}, LIMITS, X0)
    assert len(plan.steps) == len(steps) > 0
    assert plan.duration_s > 0
    assert all(s.estimate_s >= 0 for s in plan.steps)


def test_paper_defaults():
    tlre, _ = dry_run(get_protocol("tlre"), {}, LIMITS, X0)
    assert tlre.parameters["fn_N"] == 300.0 and tlre.parameters["velocity_m_s"] == 1.3e-6
    assert tlre.parameters["repetitions"] == 3
    sweep, _ = dry_run(get_protocol("force_sweep"), {}, LIMITS, X0)
    assert sweep.parameters["forces_N"] == (150.0, 175.0, 200.0, 250.0, 300.0, 350.0)
    nlre, _ = dry_run(get_protocol("nlre"), {}, LIMITS, X0)
    assert nlre.parameters["peak_N"] == 500.0 and nlre.parameters["interval_s"] == 60.0
    shs, _ = dry_run(get_protocol("slide_hold_slide"), {}, LIMITS, X0)
    holds = shs.parameters["holds_s"]
    assert max(holds) / min(holds) >= 100  # two decades
    # slides take what they should: 3 x 270 um at 1.3 um/s
    slides = [s for s in tlre.steps if s.description.startswith("slide")]
    assert sum(s.estimate_s for s in slides) == pytest.approx(3 * 270e-6 / 1.3e-6)


@pytest.mark.parametrize(
    ("name", "params", "words"),
    [
        ("tlre", {"fn_N": "700"}, ["pre-load 840 N", "800 N"]),
        ("nlre", {"peak_N": "900"}, ["900 N", "limit 800 N"]),
        ("tlre", {"travel_m": "0.15"}, ["outside the stroke"]),
        ("velocity_steps", {"velocities_m_s": "1e-5,0.01"}, ["velocity 0.01 m/s", "limit"]),
        ("tlre", {"preload_factor": "0.5"}, ["pre-load factor"]),
    ],
)
def test_violations_are_refused_before_anything_moves(name, params, words):
    with pytest.raises(PlanError) as info:
        dry_run(get_protocol(name), params, LIMITS, X0)
    text = str(info.value)
    assert text.startswith("step '")
    for w in words:
        assert w in text


def test_a_negative_magnitude_is_refused_at_the_parameter():
    """Before any step is planned: the parameter is named, not the step it would have broken."""
    with pytest.raises(PlanError, match="parameter 'holds_s': -5 s is negative"):
        dry_run(get_protocol("slide_hold_slide"), {"holds_s": "1,-5"}, LIMITS, X0)


@pytest.mark.parametrize(
    "params", [{"nonsense": "1"}, {"fn_N": "abc"}, {"fn_N": "nan"}, {"repetitions": "2.5"},
               {"fn_N": "1,2"}]
)
def test_bad_parameters_are_named(params):
    with pytest.raises(PlanError, match=next(iter(params))):
        dry_run(get_protocol("tlre"), params, LIMITS, X0)


def test_unknown_protocol():
    with pytest.raises(ValueError, match="known: nlre"):
        get_protocol("tlre2")
