"""Protocols declare their parameters once, as typed fields, and build from typed values."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from experiments.params import resolve
from experiments.protocols import PROTOCOLS, TlreParams
from experiments.runner import build_steps


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_param_defs_come_from_the_typed_fields(name: str) -> None:
    protocol = PROTOCOLS[name]
    fields = dataclasses.fields(protocol.values)
    hints = typing.get_type_hints(protocol.values)
    assert [d.name for d in protocol.params] == [f.name for f in fields]
    for d, f in zip(protocol.params, fields, strict=True):
        assert d.default == f.default
        kind = hints[f.name]
        if d.is_list:
            assert kind == tuple[float, ...]
        else:
            assert isinstance(d.default, kind)
        assert d.unit and d.doc


def test_build_reads_typed_values() -> None:
    seen: list[TlreParams] = []
    tlre = PROTOCOLS["tlre"]
    original = tlre.build
    try:
        object.__setattr__(tlre, "build", lambda p: seen.append(p) or original(p))
        params, steps = build_steps(tlre, {"repetitions": "2", "fn_N": "250"})
    finally:
        object.__setattr__(tlre, "build", original)
    (p,) = seen
    assert isinstance(p, TlreParams)
    assert p.repetitions == 2 and isinstance(p.repetitions, int)
    assert p.fn_N == 250.0 and p.preload_factor == 1.2
    assert params == dataclasses.asdict(p) == resolve(tlre.params, {"repetitions": "2", "fn_N": "250"},
                                                      "tlre")
    assert sum(s.describe().startswith("slide") for s in steps) == 2


def test_counts_and_lists_past_the_step_limit_are_refused_before_building() -> None:
    from experiments.errors import PlanError
    from experiments.params import MAX_PLAN_STEPS, check_step_count

    tlre, sweep = PROTOCOLS["tlre"], PROTOCOLS["force_sweep"]
    with pytest.raises(PlanError, match="'repetitions': 1,000,000,000 is more than a plan may hold"):
        resolve(tlre.params, {"repetitions": "1e9"}, "tlre")
    too_many = ",".join(["200"] * (MAX_PLAN_STEPS + 1))
    with pytest.raises(PlanError, match="'forces_N': 10,001 values"):
        resolve(sweep.params, {"forces_N": too_many}, "force_sweep")
    assert resolve(tlre.params, {"repetitions": str(MAX_PLAN_STEPS)}, "tlre")["repetitions"] == \
        MAX_PLAN_STEPS
    check_step_count(MAX_PLAN_STEPS, "tlre")
    with pytest.raises(PlanError, match="tlre: 10,001 steps, more than a plan may hold"):
        check_step_count(MAX_PLAN_STEPS + 1, "tlre")


def test_a_parameter_given_twice_is_refused_not_the_last_taken() -> None:
    from experiments.errors import PlanError
    from experiments.params import parse_assignments

    assert parse_assignments(["fn_N=300", "holds_s=1,10"]) == {"fn_N": "300", "holds_s": "1,10"}
    with pytest.raises(PlanError, match=r"--param fn_N is given twice \(300 and 250\)"):
        parse_assignments(["fn_N=300", " fn_N = 250"])


def test_the_steps_built_are_counted_while_they_are_planned() -> None:
    """Ten thousand repetitions pass the parameter's bound but build 60,000 steps: refused before
    the dry run plans more than the limit (a step breaking a limit before it is named first)."""
    import time

    from experiments.errors import PlanError
    from experiments.runner import dry_run
    from rigctl.config.loader import default_config
    from rigctl.rigs import rig_limits

    t0 = time.monotonic()
    with pytest.raises(PlanError, match=r"protocol tlre: [0-9,]+ steps, more than a plan may hold"):
        dry_run(PROTOCOLS["tlre"], {"repetitions": "10000"}, rig_limits(default_config()), 0.1)
    assert time.monotonic() - t0 < 10.0
