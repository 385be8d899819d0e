"""The experiment protocols: each a plain function from parameters to a list of steps.

Defaults are the paper's (Han et al. 2022, Secs. 2.1-2.2 and 4.1) where it gives them; the rest are
marked as choices in docs/experiments.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from experiments.normal_load import LoadNormal, ReleaseNormal
from experiments.params import ParamDef
from experiments.recentre import recentred
from experiments.steps import Hold, MoveTangential, ReturnTangential, Step

P = TypeVar("P")


def param(default: float | int | tuple[float, ...], unit: str, doc: str) -> Any:
    """A protocol parameter: a typed field of a protocol's parameter class carrying its
    :class:`ParamDef` (default, unit, meaning), from which ``--list-params``, the GUI's table and
    ``--param`` parsing are made."""
    return dataclasses.field(default=default, metadata={"param": (unit, doc)})


def preload_factor() -> Any:
    return param(1.2, "-", "pre-load overshoot before each tangential run "
                 "(paper Sec. 2.1, after Rubinstein; 1 = none)")


def preload_hold_s() -> Any:
    return param(5.0, "s", "hold at the pre-load")


def settle_s() -> Any:
    return param(5.0, "s", "rest at the set force before sliding")


def recentre_probes() -> Any:
    return param(1.0, "-", "1: re-centre the probes' mounts while the stage slides (the drive goes "
                 "on), keeping delta within their 74 um (docs/experiments.md); 0: never")


def recentre_headroom_m() -> Any:
    return param(40e-6, "m", "range kept ahead of a probe's reading in the slide's direction: "
                 "with less left its mount moves it back (choice: the 40 um initial-stage slip)")


def travel_m() -> Any:
    return param(270e-6, "m", "slide per run: the initial stage (~115 um at 300 N) "
                 "and about four stable cycles (choice)")


@dataclass(frozen=True)
class Protocol(Generic[P]):
    """A named protocol: its parameter class (typed fields made with :func:`param`) and the function
    from those parameters to the steps."""

    name: str
    summary: str
    values: type[P]
    build: Callable[[P], list[Step]]

    @property
    def params(self) -> tuple[ParamDef, ...]:
        """The parameters' declarations, in the order of the parameter class's fields."""
        return tuple(
            ParamDef(f.name, f.default, *f.metadata["param"])  # type: ignore[arg-type]
            for f in dataclasses.fields(self.values)  # type: ignore[arg-type]
        )

    def steps(self, params: Mapping[str, Any]) -> list[Step]:
        """The steps for resolved parameter values (:func:`experiments.params.resolve`)."""
        return self.build(self.values(**params))


class Loading:
    """What every protocol that loads the contact before sliding has (pre-load, hold, settle, the
    probes' re-centring)."""

    preload_factor: float
    preload_hold_s: float
    settle_s: float
    recentre_probes: float
    recentre_headroom_m: float


@dataclass(frozen=True)
class NlreParams:
    peak_N: float = param(500.0, "N", "peak normal force (paper: 500 N)")
    repetitions: int = param(3, "-", "loadings (paper: 3)")
    interval_s: float = param(60.0, "s", "time between loadings (paper: 60 s)")
    dwell_s: float = param(1.0, "s", "hold at the peak (choice)")
    load_velocity_m_s: float = param(20e-6, "m/s", "normal stage speed while loading")


@dataclass(frozen=True)
class TlreParams(Loading):
    fn_N: float = param(300.0, "N", "normal force (paper: 300 N)")
    velocity_m_s: float = param(1.3e-6, "m/s", "tangential drive (paper: 1.3 um/s)")
    travel_m: float = travel_m()
    repetitions: int = param(3, "-", "repetitions (paper: 3)")
    preload_factor: float = preload_factor()
    preload_hold_s: float = preload_hold_s()
    settle_s: float = settle_s()
    recentre_probes: float = recentre_probes()
    recentre_headroom_m: float = recentre_headroom_m()


@dataclass(frozen=True)
class ForceSweepParams(Loading):
    forces_N: tuple[float, ...] = param((150.0, 175.0, 200.0, 250.0, 300.0, 350.0), "N",
                                        "normal forces (paper Sec. 4.1)")
    velocity_m_s: float = param(1.3e-6, "m/s", "tangential drive (paper: 1.3 um/s)")
    travel_m: float = travel_m()
    preload_factor: float = preload_factor()
    preload_hold_s: float = preload_hold_s()
    settle_s: float = settle_s()
    recentre_probes: float = recentre_probes()
    recentre_headroom_m: float = recentre_headroom_m()


@dataclass(frozen=True)
class VelocityStepsParams(Loading):
    fn_N: float = param(300.0, "N", "normal force")
    velocities_m_s: tuple[float, ...] = param((1e-6, 3e-6, 1e-5, 3e-5, 1e-5, 3e-6), "m/s",
                                              "drive velocities in order (choice: 1.5 decades up "
                                              "and down)")
    distance_m: float = param(80e-6, "m", "slide per velocity (choice)")
    preload_factor: float = preload_factor()
    preload_hold_s: float = preload_hold_s()
    settle_s: float = settle_s()
    recentre_probes: float = recentre_probes()
    recentre_headroom_m: float = recentre_headroom_m()


@dataclass(frozen=True)
class SlideHoldSlideParams(Loading):
    fn_N: float = param(300.0, "N", "normal force")
    velocity_m_s: float = param(1e-5, "m/s", "drive velocity of the slides")
    slide_m: float = param(80e-6, "m", "slide length (about two stable cycles)")
    holds_s: tuple[float, ...] = param((1.0, 3.0, 10.0, 30.0, 100.0), "s", "hold times (two decades)")
    preload_factor: float = preload_factor()
    preload_hold_s: float = preload_hold_s()
    settle_s: float = settle_s()
    recentre_probes: float = recentre_probes()
    recentre_headroom_m: float = recentre_headroom_m()


def _load(p: Loading, fn_N: float) -> list[Step]:
    return [
        LoadNormal(fn_N, preload_factor=p.preload_factor, preload_hold_s=p.preload_hold_s),
        Hold(p.settle_s, "settle"),
    ]


def _tangential_run(p: TlreParams | ForceSweepParams, fn_N: float) -> list[Step]:
    """One tangential loading run: pre-load, settle, slide, release, return to the start."""
    return [
        *_load(p, fn_N),
        MoveTangential(p.travel_m, p.velocity_m_s),
        ReleaseNormal(),
        ReturnTangential(),
    ]


def build_nlre(p: NlreParams) -> list[Step]:
    steps: list[Step] = []
    for i in range(p.repetitions):
        if i:
            steps.append(Hold(p.interval_s, "wait"))
        steps += [LoadNormal(p.peak_N, load_velocity_m_s=p.load_velocity_m_s),
                  Hold(p.dwell_s, "dwell"), ReleaseNormal()]
    return steps


def build_tlre(p: TlreParams) -> list[Step]:
    steps: list[Step] = []
    for _ in range(p.repetitions):
        steps += _tangential_run(p, p.fn_N)
    return recentred(steps, p.recentre_probes, p.recentre_headroom_m)


def build_force_sweep(p: ForceSweepParams) -> list[Step]:
    steps: list[Step] = []
    for fn in p.forces_N:
        steps += _tangential_run(p, fn)
    return recentred(steps, p.recentre_probes, p.recentre_headroom_m)


def build_velocity_steps(p: VelocityStepsParams) -> list[Step]:
    steps: list[Step] = [*_load(p, p.fn_N)]
    for v in p.velocities_m_s:
        steps.append(MoveTangential(p.distance_m, v))
    return recentred([*steps, ReleaseNormal(), ReturnTangential()], p.recentre_probes, p.recentre_headroom_m)


def build_slide_hold_slide(p: SlideHoldSlideParams) -> list[Step]:
    steps: list[Step] = [*_load(p, p.fn_N), MoveTangential(p.slide_m, p.velocity_m_s)]
    for hold in p.holds_s:
        steps += [Hold(hold), MoveTangential(p.slide_m, p.velocity_m_s)]
    return recentred([*steps, ReleaseNormal(), ReturnTangential()], p.recentre_probes, p.recentre_headroom_m)


PROTOCOLS: dict[str, Protocol[Any]] = {
    p.name: p
    for p in (
        Protocol(
            "nlre", "normal loading repeatability: load to 500 N and unload, 3 times, 60 s apart "
            "(paper Sec. 2.2)",
            NlreParams, build_nlre,
        ),
        Protocol(
            "tlre", "tangential loading repeatability: 300 N, 1.3 um/s, 3 repetitions, stage "
            "returned to the start after each (paper Sec. 2.2)",
            TlreParams, build_tlre,
        ),
        Protocol(
            "force_sweep", "TLRE at 150, 175, 200, 250, 300, 350 N (paper Sec. 4.1)",
            ForceSweepParams, build_force_sweep,
        ),
        Protocol(
            "velocity_steps", "slides at stepped drive velocities (up and down) at one normal "
            "force, to expose rate effects",
            VelocityStepsParams, build_velocity_steps,
        ),
        Protocol(
            "slide_hold_slide", "slides separated by holds spanning two decades, to expose aging",
            SlideHoldSlideParams, build_slide_hold_slide,
        ),
    )
}
