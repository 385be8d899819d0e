"""``track_waviness``: a worked example of a new term in the equations of motion - friction that
rises and falls with the position along the track.

    mu(X) = mu (1 + a sin(2 pi X / lambda + phi))

applied to the static and the kinetic coefficient alike (X the slider's position). A lead-screw
whose pitch shows in the stage's straightness, a track ground with a periodic waviness or a motor's
cogging make friction periodic in position (e.g. Armstrong-Helouvry, Dupont & Canudas de Wit,
Automatica 30 (1994), section 2.5, "position dependence"). Peaks and troughs then rise and fall
with a period of lambda of track. Off: a = 0.

Tested with ``rigctl.testing.EffectContract`` in ``tests/model/test_plugin_terms.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from rigctl.model import Effect, ParamSpec


def waviness_mu(p: np.ndarray, mu: float, x_m: float, v_m_s: float, t_s: float, fn_N: float,
                stick_s: float, z: np.ndarray) -> float:
    """The friction term: p = (amplitude, wavelength_m, phase_rad), in the order of ``params``."""
    return mu * (1.0 + p[0] * math.sin(2.0 * math.pi * x_m / p[1] + p[2]))


class TrackWaviness(Effect):
    name = "track_waviness"
    summary = "friction periodic in the position along the track"
    signature = "peaks and troughs rise and fall with the slider's position (period lambda)"
    reveal_protocol = "a long slide over several wavelengths at constant velocity and load"
    params = (
        ParamSpec("amplitude", 0.05, 0.0, 0.5, "-", "relative amplitude a of the waviness",
                  off=0.0),
        ParamSpec("wavelength_m", 2e-4, 2e-5, 1e-2, "m", "period lambda along the track",
                  off=2e-4, scales_with="slip_length"),
        ParamSpec("phase_rad", 0.0, -math.pi, math.pi, "rad", "phase phi at X = 0", off=0.0),
    )

    @staticmethod
    def friction_term() -> Callable[..., Any]:
        return waviness_mu

    def terms_active(self, values: Mapping[str, float], base: Mapping[str, float]) -> bool:
        return values["amplitude"] != 0.0  # the wavelength and phase matter only with it
