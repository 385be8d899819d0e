"""A run being recorded, for the Runs tab's tests: a stick-slip record written to an HDF5 run file in
pieces of ``CHUNK_S`` of samples every ``PERIOD_S`` of wall time (flushed each time, as the recorder
does), 'ready' printed after the first flush, closed ``completed`` once all is written.

``python -m tests.gui.growing_run_writer OUT.h5 DURATION_S``
"""

from __future__ import annotations

import sys
import time

from rigctl.storage import RunWriter
from rigctl.storage.layout import DaqLayout, RunDescription
from tests.workbench.synth import sawtooth_run

CHUNK_S = 1.0
PERIOD_S = 0.5
PARAMETERS = {"fn_N": 250.0, "velocity_m_s": 1e-5, "travel_m": 1.6e-4, "repetitions": 1}


def description() -> RunDescription:
    return RunDescription(protocol="tlre", parameters=PARAMETERS, operator="tester",
                          config_toml="[rig]\nname = \"test rig\"\n")


def write_run(path: str, duration_s: float, period_s: float = PERIOD_S) -> None:
    """Write the run; ``period_s`` of wall time between pieces (0: all at once)."""
    run, _ = sawtooth_run(duration_s=duration_s, t_load_start_s=1.0, seed=3)
    cols = run.columns()
    fs = run.sample_rate_hz
    w = RunWriter(path, description(), DaqLayout(channels=tuple(k for k in cols if k != "t_s")),
                  min_free_bytes=0)
    step = int(CHUNK_S * fs)
    w.add_event(float(run.t_s[0]), "start", "protocol tlre")
    for i, a in enumerate(range(0, run.n_samples, step)):
        w.append_daq({k: v[a : a + step] for k, v in cols.items()})
        w.flush()
        if i == 0 and period_s > 0:
            print("ready", flush=True)
        time.sleep(period_s)
    w.add_event(float(run.t_s[-1]), "end", "all written")
    w.close()


if __name__ == "__main__":
    write_run(sys.argv[1], float(sys.argv[2]))
