"""The stick-slip physics model of the rig: engine, parameters, effect library, plug-ins.

    from rigctl.model import build_model, Simulator, Drive
    res = Simulator(build_model("paper")).run(Drive.constant(300.0, 1e-5, 60.0))
"""

from __future__ import annotations

from rigctl.model.drive import MAX_NORMAL_FORCE_N, Drive
from rigctl.model.effects import LIBRARY, CoreParams, Effect, LinearTerms, SlipContext
from rigctl.model.noise import NoiseModel
from rigctl.model.params import ParameterError, ParamInfo, ParamSpec
from rigctl.model.result import SimResult, SlipEvent
from rigctl.model.simulator import Simulator, Stepper, StepperState, TimeLimitError, run_clock
from rigctl.model.spec import BASES, ModelSpec, build_model, effect_names

__all__ = [
    "BASES",
    "LIBRARY",
    "MAX_NORMAL_FORCE_N",
    "CoreParams",
    "Drive",
    "Effect",
    "LinearTerms",
    "ModelSpec",
    "NoiseModel",
    "ParamInfo",
    "ParamSpec",
    "ParameterError",
    "SimResult",
    "Simulator",
    "SlipContext",
    "SlipEvent",
    "Stepper",
    "StepperState",
    "TimeLimitError",
    "build_model",
    "effect_names",
    "run_clock",
]
