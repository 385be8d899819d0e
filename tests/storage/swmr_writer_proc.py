"""A real-time run writer for the SWMR tests, run as a separate process.

Usage: python swmr_writer_proc.py PATH DURATION_S

Writes the default DAQ channels at 1024 Hz in blocks of 64 samples, each block appended once its
last sample's time has passed (as a DAQ would deliver it). Channel values are a known function of
time (see ``expected``), so a reader can check every sample. Prints ``ready <t0>`` (t0 on the
system-wide monotonic clock, the time of sample t = 0) once the file is in SWMR mode,
``appended <t>`` after each block (t: its last sample time), and ``done <n>`` after a clean close.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from rigctl.storage import DaqLayout, RunDescription, RunWriter

RATE_HZ = 1024.0
BLOCK = 64


def expected(name_index: int, t_s: np.ndarray) -> np.ndarray:
    """Value of channel number ``name_index`` at times ``t_s``."""
    return np.sin(t_s * (name_index + 1)) + name_index


def main() -> None:
    path, duration_s = sys.argv[1], float(sys.argv[2])
    daq = DaqLayout(sample_rate_hz=RATE_HZ)
    writer = RunWriter(path, RunDescription(protocol="swmr-test"), daq)
    t0 = time.monotonic()
    print(f"ready {t0!r}", flush=True)
    k = 0
    while True:
        t = (np.arange(BLOCK) + k * BLOCK) / RATE_HZ
        if t[0] >= duration_s:
            break
        wait = t0 + t[-1] - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        block = {"t_s": t} | {name: expected(i, t) for i, name in enumerate(daq.channels)}
        writer.append_daq(block, counter=k * BLOCK, host_time_s=time.monotonic())
        print(f"appended {float(t[-1])!r}", flush=True)
        k += 1
    writer.close("completed")
    print(f"done {k * BLOCK}", flush=True)


if __name__ == "__main__":
    main()
