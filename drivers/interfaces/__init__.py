"""Abstract device interfaces: one class per device kind, python-microscope style.

Each public method validates its arguments (finite numbers, limits, interlocks) and then calls a
protected ``_do_...`` hook that a concrete driver (``drivers/``) or simulator
(``sim_devices/``) implements. Validation therefore happens once, here, before anything reaches
a wire: a command beyond a limit raises :class:`~drivers.errors.LimitError` and is never clipped.

Units are SI and in the names (``target_m``, ``velocity_m_s``, ``rate_hz``, ``fx_N``, ``ain_V``).
Host timestamps are ``time.monotonic_ns()`` everywhere (DAQ blocks, probe samples, camera
frames), so streams can be aligned at analysis time.
"""

from drivers.interfaces.camera import Camera, Frame, FrameDropDetector, RawFrame
from drivers.interfaces.common import Device, FloatArray, IntArray
from drivers.interfaces.daq import ChannelMap, Daq, DaqBlock, ForceAxis
from drivers.interfaces.probe import DisplacementProbe, ProbeSamples
from drivers.interfaces.stage import MOTION_COMMANDS, LoadingStage, StageLimits, StageStatus

__all__ = [
    "MOTION_COMMANDS",
    "Camera",
    "ChannelMap",
    "Daq",
    "DaqBlock",
    "Device",
    "DisplacementProbe",
    "FloatArray",
    "ForceAxis",
    "Frame",
    "FrameDropDetector",
    "IntArray",
    "LoadingStage",
    "ProbeSamples",
    "RawFrame",
    "StageLimits",
    "StageStatus",
]
