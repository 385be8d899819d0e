"""Which edited parameter makes a dry run refuse: the GUI marks it in the parameter table.

A limit refusal (``PlanError``) names the step and the limit (``step 'load Fn to 5000 N (pre-load
6000 N)': peak normal force 6000 N exceeds the limit 800 N``), not the parameter. The parameter is
found by planning again with one edited value at a time put back to its default: an edited parameter
whose default makes the plan pass (or changes the refusal) is a cause. Only the dry run is repeated
(pure, from the same stage position, no device touched).
"""

from __future__ import annotations

from typing import Any

from experiments.context import RigLimits
from experiments.errors import PlanError
from experiments.protocols import Protocol
from experiments.runner import dry_run


def refusal_culprits(protocol: Protocol, given: dict[str, Any], limits: RigLimits,
                     x_start_m: float, refusal: str) -> tuple[str, ...]:
    """The edited parameters (keys of ``given``) that cause ``refusal``.

    First those whose default alone makes the plan pass; if none does (two values together, or the
    defaults themselves refused), those whose default changes the refusal. Empty if neither.
    """
    passing: list[str] = []
    changing: list[str] = []
    for name in given:
        trial = {k: v for k, v in given.items() if k != name}
        try:
            dry_run(protocol, trial, limits, x_start_m)
        except PlanError as exc:
            if str(exc) != refusal:
                changing.append(name)
            continue
        passing.append(name)
    return tuple(passing or changing)
