"""Write a stick-slip run with frames, flush, say 'ready', then wait to be killed (SIGKILL test)."""

from __future__ import annotations

import sys
import time

import numpy as np

from rigctl.storage import RunWriter
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from tests.workbench.synth import sawtooth_run


def main(path: str) -> None:
    run, _ = sawtooth_run(duration_s=20.0, t_load_start_s=1.0, seed=3)
    cols = run.columns()
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=32, width_px=48, frame_rate_hz=10.0)
    rng = np.random.default_rng(0)
    w = RunWriter(path, RunDescription(protocol="tlre"), daq, cam, min_free_bytes=0)
    n = run.n_samples
    for a in range(0, n, 1024):
        w.append_daq({k: v[a : a + 1024] for k, v in cols.items()})
    t_f = np.arange(0.0, float(run.t_s[-1]), 0.1)
    frames = rng.integers(0, 40, (t_f.size, 32, 48), dtype=np.uint8)
    w.append_frames(frames, t_f, np.arange(t_f.size))
    w.flush()
    print("ready", flush=True)
    time.sleep(600)


if __name__ == "__main__":
    main(sys.argv[1])
    sys.exit(0)
