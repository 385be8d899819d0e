"""The effect library: twelve named physical effects (docs/effects.md) and the plug-in base."""

from __future__ import annotations

from rigctl.model.effects.base import CoreParams, Effect, LinearTerms, SlipContext
from rigctl.model.effects.contact_degradation import ContactDegradation
from rigctl.model.effects.interface_damping import InterfaceDamping
from rigctl.model.effects.load_dependent_friction import LoadDependentFriction
from rigctl.model.effects.load_dependent_stiffness import LoadDependentStiffness
from rigctl.model.effects.normal_coupling import NormalCoupling
from rigctl.model.effects.presliding import Presliding
from rigctl.model.effects.probe_drift import ProbeDrift
from rigctl.model.effects.rate_state import RateState
from rigctl.model.effects.sensor_dynamics import SensorDynamics
from rigctl.model.effects.stress_evolution import StressEvolution
from rigctl.model.effects.stribeck import Stribeck
from rigctl.model.effects.wear import Wear

LIBRARY: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        StressEvolution,
        Stribeck,
        RateState,
        LoadDependentFriction,
        LoadDependentStiffness,
        ContactDegradation,
        Presliding,
        InterfaceDamping,
        Wear,
        NormalCoupling,
        SensorDynamics,
        ProbeDrift,
    )
}
"""The canonical effects by name, in the order of docs/effects.md."""

__all__ = ["LIBRARY", "CoreParams", "Effect", "LinearTerms", "SlipContext"]
