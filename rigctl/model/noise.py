"""Realistic sensor noise and quantisation for simulated runs (off unless asked for).

Gaussian white noise of the given RMS, then rounding to the channel's resolution (its LSB), as the
rig's acquisition chain does: force LSB 0.02 N (a DAQ of 0.02 N per count; the simulated rig's
own CAN DAQ reads 0.025 N per count, docs/protocols.md, and quantises its readings itself), probe
resolution 0.019 um (MTI-2100 + RS2032R, paper Sec. 2.1), tangential stage encoder 0.32 um.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigctl.model.result import SimResult


def _quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    return np.round(x / lsb) * lsb if lsb > 0 else x


@dataclass(frozen=True)
class NoiseModel:
    ft_rms_N: float = 0.05
    fn_rms_N: float = 0.2
    force_lsb_N: float = 0.02
    probe_rms_m: float = 0.01e-6
    probe_lsb_m: float = 0.019e-6
    stage_lsb_m: float = 0.32e-6

    def apply(self, res: SimResult, rng: np.random.Generator) -> None:
        n = res.n_samples
        res.ft_N = _quantise(res.ft_N + rng.normal(0.0, self.ft_rms_N, n), self.force_lsb_N)
        res.fn_N = _quantise(res.fn_N + rng.normal(0.0, self.fn_rms_N, n), self.force_lsb_N)
        res.d1_m = _quantise(res.d1_m + rng.normal(0.0, self.probe_rms_m, n), self.probe_lsb_m)
        res.d2_m = _quantise(res.d2_m + rng.normal(0.0, self.probe_rms_m, n), self.probe_lsb_m)
        res.x_stage_m = _quantise(res.x_stage_m, self.stage_lsb_m)

    def describe(self) -> str:
        return (
            f"ft {self.ft_rms_N} N rms, fn {self.fn_rms_N} N rms, force LSB {self.force_lsb_N} N, "
            f"probe {self.probe_rms_m} m rms, LSB {self.probe_lsb_m} m, stage LSB {self.stage_lsb_m} m"
        )
