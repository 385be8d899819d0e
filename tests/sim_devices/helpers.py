"""Small procedures the simulated-device tests share (through the public interfaces only)."""

from __future__ import annotations

import numpy as np

from drivers.interfaces import Daq
from sim_devices.backends import SimRig


def load_normal(sim: SimRig, fn_N: float, velocity_m_s: float = 2e-3) -> None:
    """Bring the specimens into contact at ``fn_N`` with the normal stage (through its driver)."""
    stage = sim.devices.normal_stage
    stage.enable()
    stage.move_absolute(sim.rig.config.contact.z_for_fn_m(fn_N), velocity_m_s)
    stage.wait_for_motion(5.0)


def move_tangential(sim: SimRig, delta_m: float, velocity_m_s: float = 1e-3) -> None:
    """Move the tangential stage by ``delta_m`` and wait for it to arrive."""
    stage = sim.devices.tangential_stage
    stage.enable()
    stage.move_relative(delta_m, velocity_m_s)
    stage.wait_for_motion(5.0)


def collect(daq: Daq, n: int, timeout_s: float = 3.0) -> dict[str, np.ndarray]:
    """``n`` samples of a started DAQ as arrays of Ft, Fn, Fy, D1, D2 [SI] and counters."""
    import time

    m = daq.channel_map
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("ft", "fn", "fy", "d1", "d2", "counter")}
    got = 0
    deadline = time.monotonic() + timeout_s
    while got < n and time.monotonic() < deadline:
        b = daq.read_block(n - got, 0.2)
        if len(b) == 0:
            continue
        parts["ft"].append(m.ft_N(b))
        parts["fn"].append(m.fn_N(b))
        parts["fy"].append(b.fy_N)
        parts["d1"].append(m.d1_m(b))
        parts["d2"].append(m.d2_m(b))
        parts["counter"].append(b.counter)
        got += len(b)
    assert got >= n, f"only {got} of {n} samples within {timeout_s} s"
    return {k: np.concatenate(v) for k, v in parts.items()}
