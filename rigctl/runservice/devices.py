"""What the Devices tab shows and does with an open rig: a status snapshot and a checked jog.

Used by the run service (which owns the rig) and by a window that holds an open rig itself. A jog is
``move_relative`` on the stage's driver, which checks the stage's limits before anything is sent and
refuses a move beyond them with a :class:`~drivers.errors.LimitError` naming the limit; the refusal's
text is what the operator sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from rigctl.rigs import OpenRig

AXES = ("tangential", "normal")


@dataclass(frozen=True)
class StageSnapshot:
    name: str
    position_m: float
    min_position_m: float
    max_position_m: float
    max_velocity_m_s: float
    enabled: bool = False
    moving: bool = False
    fault: bool = False
    alarm: str = "none"
    error: str = ""
    """A failed read of this stage (the device's error text)."""


@dataclass(frozen=True)
class RigSnapshot:
    stages: dict[str, StageSnapshot]
    estop: str | None
    """The latched emergency stop's reason, None when not triggered."""
    readings: dict[str, float] = field(default_factory=dict)
    """Latest DAQ values (Ft, Fn, d1, d2, ...) while a run records; empty otherwise."""
    busy: bool = False


def _stage(rig: OpenRig, axis: str) -> Any:
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
    return rig.devices.tangential_stage if axis == "tangential" else rig.devices.normal_stage


def snapshot(rig: OpenRig, readings: dict[str, float] | None = None, busy: bool = False) -> RigSnapshot:
    """Every stage's position, limits and status bits; a stage that cannot be read says why."""
    stages = {}
    for axis in AXES:
        stage = _stage(rig, axis)
        lim = stage.limits
        try:
            st = stage.status()
            stages[axis] = StageSnapshot(axis, stage.position_m(), lim.min_position_m, lim.max_position_m,
                                         lim.max_velocity_m_s, st.enabled, st.moving, st.fault,
                                         st.alarm_name)
        except Exception as exc:  # a device error is shown, not raised into the window
            stages[axis] = StageSnapshot(axis, math.nan, lim.min_position_m, lim.max_position_m,
                                         lim.max_velocity_m_s, error=str(exc))
    estop = rig.devices.tangential_stage.emergency_stop_registry.reason
    return RigSnapshot(stages, estop, dict(readings or {}), busy)


def jog(rig: OpenRig, axis: str, delta_m: float, velocity_m_s: float) -> None:
    """Move ``axis`` by ``delta_m`` at ``velocity_m_s`` (enabling it first); the driver refuses a move
    beyond the limits (LimitError), an e-stop in force (EmergencyStopActive) or a bad value."""
    stage = _stage(rig, axis)
    target = stage.position_m() + delta_m
    stage.check_move(target, velocity_m_s)  # refused here, before the stage is even enabled
    if not stage.status().enabled:
        stage.enable()
    stage.move_absolute(target, velocity_m_s)


def reset_emergency_stop(rig: OpenRig) -> list[str]:
    """Unlatch the emergency stop and clear the stages' e-stop alarms; returns what failed.

    The stages stay where they stopped; motion commands are accepted again."""
    problems = []
    for axis in AXES:
        stage = _stage(rig, axis)
        stage.emergency_stop_registry.reset()
        try:
            if stage.status().fault:
                stage.reset_alarm()
        except Exception as exc:
            problems.append(f"{axis}: {exc}")
    return problems
