"""The experiment protocols: each a plain function from parameters to a list of steps.

Defaults are the paper's (Han et al. 2022, Secs. 2.1-2.2 and 4.1) where it gives them; the rest are
marked as choices in docs/experiments.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from experiments.normal_load import LoadNormal, ReleaseNormal
from experiments.params import ParamDef
from experiments.steps import Hold, MoveTangential, ReturnTangential, Step

PRELOAD = ParamDef("preload_factor", 1.2, "-", "pre-load overshoot before each tangential run "
                   "(paper Sec. 2.1, after Rubinstein; 1 = none)")
PRELOAD_HOLD = ParamDef("preload_hold_s", 5.0, "s", "hold at the pre-load")
SETTLE = ParamDef("settle_s", 5.0, "s", "rest at the set force before sliding")


@dataclass(frozen=True)
class Protocol:
    name: str
    summary: str
    params: tuple[ParamDef, ...]
    build: Callable[[dict[str, Any]], list[Step]]


def _load(p: dict[str, Any], fn_N: float) -> list[Step]:
    return [
        LoadNormal(fn_N, preload_factor=p["preload_factor"], preload_hold_s=p["preload_hold_s"]),
        Hold(p["settle_s"], "settle"),
    ]


def _tangential_run(p: dict[str, Any], fn_N: float) -> list[Step]:
    """One tangential loading run: pre-load, settle, slide, release, return to the start."""
    return [
        *_load(p, fn_N),
        MoveTangential(p["travel_m"], p["velocity_m_s"]),
        ReleaseNormal(),
        ReturnTangential(),
    ]


def build_nlre(p: dict[str, Any]) -> list[Step]:
    steps: list[Step] = []
    for i in range(p["repetitions"]):
        if i:
            steps.append(Hold(p["interval_s"], "wait"))
        steps += [LoadNormal(p["peak_N"], load_velocity_m_s=p["load_velocity_m_s"]),
                  Hold(p["dwell_s"], "dwell"), ReleaseNormal()]
    return steps


def build_tlre(p: dict[str, Any]) -> list[Step]:
    steps: list[Step] = []
    for _ in range(p["repetitions"]):
        steps += _tangential_run(p, p["fn_N"])
    return steps


def build_force_sweep(p: dict[str, Any]) -> list[Step]:
    steps: list[Step] = []
    for fn in p["forces_N"]:
        steps += _tangential_run(p, fn)
    return steps


def build_velocity_steps(p: dict[str, Any]) -> list[Step]:
    steps: list[Step] = [*_load(p, p["fn_N"])]
    for v in p["velocities_m_s"]:
        steps.append(MoveTangential(p["distance_m"], v))
    return [*steps, ReleaseNormal(), ReturnTangential()]


def build_slide_hold_slide(p: dict[str, Any]) -> list[Step]:
    steps: list[Step] = [*_load(p, p["fn_N"]), MoveTangential(p["slide_m"], p["velocity_m_s"])]
    for hold in p["holds_s"]:
        steps += [Hold(hold), MoveTangential(p["slide_m"], p["velocity_m_s"])]
    return [*steps, ReleaseNormal(), ReturnTangential()]


TRAVEL = ParamDef("travel_m", 270e-6, "m", "slide per run: the initial stage (~115 um at 300 N) "
                  "and about four stable cycles (choice)")
PROTOCOLS: dict[str, Protocol] = {
    p.name: p
    for p in (
        Protocol(
            "nlre", "normal loading repeatability: load to 500 N and unload, 3 times, 60 s apart "
            "(paper Sec. 2.2)",
            (
                ParamDef("peak_N", 500.0, "N", "peak normal force (paper: 500 N)"),
                ParamDef("repetitions", 3, "-", "loadings (paper: 3)"),
                ParamDef("interval_s", 60.0, "s", "time between loadings (paper: 60 s)"),
                ParamDef("dwell_s", 1.0, "s", "hold at the peak (choice)"),
                ParamDef("load_velocity_m_s", 20e-6, "m/s", "normal stage speed while loading"),
            ),
            build_nlre,
        ),
        Protocol(
            "tlre", "tangential loading repeatability: 300 N, 1.3 um/s, 3 repetitions, stage "
            "returned to the start after each (paper Sec. 2.2)",
            (
                ParamDef("fn_N", 300.0, "N", "normal force (paper: 300 N)"),
                ParamDef("velocity_m_s", 1.3e-6, "m/s", "tangential drive (paper: 1.3 um/s)"),
                TRAVEL,
                ParamDef("repetitions", 3, "-", "repetitions (paper: 3)"),
                PRELOAD, PRELOAD_HOLD, SETTLE,
            ),
            build_tlre,
        ),
        Protocol(
            "force_sweep", "TLRE at 150, 175, 200, 250, 300, 350 N (paper Sec. 4.1)",
            (
                ParamDef("forces_N", (150.0, 175.0, 200.0, 250.0, 300.0, 350.0), "N",
                         "normal forces (paper Sec. 4.1)"),
                ParamDef("velocity_m_s", 1.3e-6, "m/s", "tangential drive (paper: 1.3 um/s)"),
                TRAVEL, PRELOAD, PRELOAD_HOLD, SETTLE,
            ),
            build_force_sweep,
        ),
        Protocol(
            "velocity_steps", "slides at stepped drive velocities (up and down) at one normal "
            "force, to expose rate effects",
            (
                ParamDef("fn_N", 300.0, "N", "normal force"),
                ParamDef("velocities_m_s", (1e-6, 3e-6, 1e-5, 3e-5, 1e-5, 3e-6), "m/s",
                         "drive velocities in order (choice: 1.5 decades up and down)"),
                ParamDef("distance_m", 80e-6, "m", "slide per velocity (choice)"),
                PRELOAD, PRELOAD_HOLD, SETTLE,
            ),
            build_velocity_steps,
        ),
        Protocol(
            "slide_hold_slide", "slides separated by holds spanning two decades, to expose aging",
            (
                ParamDef("fn_N", 300.0, "N", "normal force"),
                ParamDef("velocity_m_s", 1e-5, "m/s", "drive velocity of the slides"),
                ParamDef("slide_m", 80e-6, "m", "slide length (about two stable cycles)"),
                ParamDef("holds_s", (1.0, 3.0, 10.0, 30.0, 100.0), "s",
                         "hold times (two decades)"),
                PRELOAD, PRELOAD_HOLD, SETTLE,
            ),
            build_slide_hold_slide,
        ),
    )
}
