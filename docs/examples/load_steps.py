"""``load_steps``: a worked example of a protocol file - normal-force steps under one contact.

One loading, then a slide at each normal force in turn, the force changed between slides while the
tangential stage stands still; the load is released and the stage returned to its start at the end.
Unlike the built-in ``force_sweep`` (a full TLRE per force: unload, return, re-load with pre-load),
the contact is never renewed, so load-dependent friction and stiffness are seen on one contact
without re-loading and ageing between the forces.

Run it from its path (nothing is installed or registered; the file is loaded from this path only):

    rigctl run docs/examples/load_steps.py --list-params
    rigctl run docs/examples/load_steps.py --dry-run --param forces_N=200,300,400
    rigctl run docs/examples/load_steps.py --speed max --out runs/load_steps.h5

The file defines a ``Protocol``: its parameter class (a frozen dataclass whose fields are made with
``param(default, unit, doc)``: typed, with units, shown by ``--list-params`` and set by
``--param NAME=VALUE``) and a ``build`` function from those parameters to the library's steps. The
dry run checks every step against the rig's limits, and a run that does not complete ends in the
safe state, exactly as for the built-in protocols.
"""

from __future__ import annotations

from dataclasses import dataclass

from experiments.normal_load import LoadNormal, ReleaseNormal
from experiments.protocols import Protocol, param
from experiments.steps import Hold, MoveTangential, ReturnTangential, Step


@dataclass(frozen=True)
class LoadStepsParams:
    forces_N: tuple[float, ...] = param((200.0, 300.0, 400.0), "N",
                                        "normal forces, one slide at each, in this order")
    velocity_m_s: float = param(1e-5, "m/s", "tangential drive velocity of the slides")
    slide_m: float = param(100e-6, "m", "slide at each force (a few stick-slip cycles)")
    settle_s: float = param(2.0, "s", "rest after each change of the normal force")
    preload_factor: float = param(1.2, "-", "pre-load overshoot of the first loading (1 = none)")
    preload_hold_s: float = param(5.0, "s", "hold at the pre-load")


def build(p: LoadStepsParams) -> list[Step]:
    steps: list[Step] = []
    for i, fn_N in enumerate(p.forces_N):
        if i == 0:  # the first loading, with the paper's pre-load (Sec. 2.1)
            steps.append(LoadNormal(fn_N, preload_factor=p.preload_factor,
                                    preload_hold_s=p.preload_hold_s))
        else:  # the contact stays: only the force changes
            steps.append(LoadNormal(fn_N))
        steps += [Hold(p.settle_s, "settle"), MoveTangential(p.slide_m, p.velocity_m_s)]
    return [*steps, ReleaseNormal(), ReturnTangential()]


PROTOCOL = Protocol(
    "load_steps",
    "one loading, a slide at each normal force in turn (no unloading between), release, return",
    LoadStepsParams,
    build,
)
