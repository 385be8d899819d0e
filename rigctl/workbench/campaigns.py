"""Simulated campaigns: the protocols that reveal each effect, run on any model with sensor noise.

A campaign is a list of runs (``rigctl.data.MeasuredRun``), like a folder of CSV files from the rig.
The protocols are the paper's and those the effects reveal themselves in (docs/effects.md):

==================  ===========================================================================
``tlre``            one tangential-loading run from rest (paper Sec. 2.2): Fn = 300 N, 10 um/s
``force_sweep``     one run per normal force (paper Sec. 4): 250 ... 450 N at 10 um/s
``velocity_steps``  stage velocity stepped over a decade: 5, 15, 50, 5 um/s, at Fn and at Fn / 2
``slide_hold_slide``slides of 20 um/s separated by holds of 1, 3, 10 and 30 s
``long_run``        a long run with many cycles (20 um/s)
==================  ===========================================================================

``PROTOCOL_FOR_EFFECT`` names, for each library effect, the protocol whose data show it (its
signature, docs/effects.md); the hidden-effect tests and benchmark use it, and users can
generate the same campaigns to see what a protocol can tell apart (``duration_scale`` shortens or
lengthens every segment).

Why ``velocity_steps`` runs at two loads: velocity weakening (``stribeck``) acts on the *slip*
velocity, and that is set by the slip's own dynamics, not by the drive: a slip of drop dF in a
contact of stiffness k and mass m runs at about dF / sqrt(k m) (70 mm/s at 300 N in the simulated
rig), whatever the stage does at 5-50 um/s. Halving Fn halves the drop and the slip velocity, so the
same velocity steps at two loads move the slips across v_s. At one load only, a weakening whose v_s
lies well below the slip velocity is just a lower mu_k (docs/validation.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from rigctl.data import MeasuredRun
from rigctl.errors import InputError
from rigctl.model import Drive, ModelSpec, NoiseModel, Simulator

PROTOCOLS: tuple[str, ...] = (
    "tlre", "force_sweep", "velocity_steps", "slide_hold_slide", "long_run",
)

PROTOCOL_FOR_EFFECT: dict[str, str] = {
    "stress_evolution": "tlre",
    "stribeck": "velocity_steps",
    "rate_state": "slide_hold_slide",
    "load_dependent_friction": "force_sweep",
    "load_dependent_stiffness": "force_sweep",
    "contact_degradation": "long_run",
    "presliding": "tlre",
    "interface_damping": "tlre",
    "wear": "long_run",
    "normal_coupling": "tlre",
    "sensor_dynamics": "tlre",
    "probe_drift": "long_run",
}


@dataclass(frozen=True)
class RunPlan:
    """One run of a protocol: a label and its drive."""

    label: str
    drive: Drive


def protocol_runs(
    protocol: str, fn_N: float = 300.0, velocity_m_s: float = 1e-5, duration_scale: float = 1.0
) -> list[RunPlan]:
    """The runs of a protocol (durations multiplied by ``duration_scale``)."""
    s = float(duration_scale)
    v = float(velocity_m_s)
    if protocol == "tlre":
        return [RunPlan(f"tlre_{fn_N:g}N", Drive.constant(fn_N, v, 60.0 * s))]
    if protocol == "force_sweep":
        return [
            RunPlan(f"sweep_{f:g}N", Drive.constant(f, v, 30.0 * s))
            for f in (fn_N - 50.0, fn_N, fn_N + 50.0, fn_N + 100.0, fn_N + 150.0)
        ]
    if protocol == "velocity_steps":
        segs = [(30.0 * s, 0.5 * v), (15.0 * s, 1.5 * v), (10.0 * s, 5.0 * v), (25.0 * s, 0.5 * v)]
        # the same steps at half the load: slower slips (see the module docstring)
        return [RunPlan(f"vsteps_{f:g}N", Drive.segments(f, segs)) for f in (fn_N, 0.5 * fn_N)]
    if protocol == "slide_hold_slide":
        segs = [(20.0 * s, 2.0 * v)]
        for hold in (1.0, 3.0, 10.0, 30.0):
            segs += [(hold, 0.0), (15.0 * s, 2.0 * v)]
        return [RunPlan(f"shs_{fn_N:g}N", Drive.segments(fn_N, segs))]
    if protocol == "long_run":
        return [RunPlan(f"long_{fn_N:g}N", Drive.constant(fn_N, 2.0 * v, 120.0 * s))]
    raise InputError(f"unknown protocol '{protocol}' (known: {', '.join(PROTOCOLS)})")


def simulate_campaign(
    model: ModelSpec,
    protocol: str,
    *,
    seed: int = 0,
    noise: bool | NoiseModel = True,
    sample_rate_hz: float = 1024.0,
    fn_N: float = 300.0,
    velocity_m_s: float = 1e-5,
    duration_scale: float = 1.0,
) -> list[MeasuredRun]:
    """Runs of ``protocol`` simulated with ``model`` (noise and quantisation on by default)."""
    sim = Simulator(model, sample_rate_hz=sample_rate_hz)
    runs = []
    for i, plan in enumerate(protocol_runs(protocol, fn_N, velocity_m_s, duration_scale)):
        res = sim.run(plan.drive, noise=noise, seed=seed * 1000 + i, record_elements=False)
        run = res.to_measured()
        run.source = plan.label
        run.metadata.update({"protocol": protocol, "run": plan.label})
        runs.append(run)
    return runs


def write_campaign(runs: Sequence[MeasuredRun], folder: str | Path) -> list[Path]:
    """Write a campaign as exchange-format CSV files (one per run) into ``folder``."""
    from rigctl.io.csv_format import write_csv

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, run in enumerate(runs):
        name = Path(run.source).stem if run.source else f"run{i + 1}"
        path = out / f"{i + 1:02d}_{name}.csv"
        write_csv(path, run)
        paths.append(path)
    return paths


def describe_protocols(present: Mapping[str, bool]) -> str:
    return ", ".join(p for p, ok in present.items() if ok) or "none"
