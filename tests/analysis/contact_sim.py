"""Simulated runs with camera frames for the contact-image tests: the model's run, rendered.

Frames are rendered by the simulated camera (:class:`sim_devices.contact_image.ContactImageRenderer`)
from the model's contact state at each frame time (its stage's P table, Fn and the sliding elements),
as the virtual rig does, and written with the DAQ samples into a run file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.model import SimResult
from rigctl.storage import RunWriter
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from sim_devices.contact_image import CameraOptics, ContactImageRenderer


def write_with_frames(path: Path, res: SimResult, run: MeasuredRun, rate_hz: float = 30.0,
                      optics: CameraOptics | None = None, t_from_s: float = 0.0,
                      protocol: str = "sim", parameters: dict[str, Any] | None = None) -> Path:
    """``run`` (the model's samples with noise) and frames of ``res`` at ``rate_hz`` from ``t_from_s``.

    The file names ``protocol`` and its ``parameters`` as a recorded run does.
    """
    optics = optics or CameraOptics(width_px=160, height_px=120, read_noise_rms=1.2)
    renderer = ContactImageRenderer(optics)
    cols = run.columns()
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=optics.height_px, width_px=optics.width_px, frame_rate_hz=rate_hz)
    t_frames = np.arange(t_from_s, float(res.t_s[-1]), 1.0 / rate_hz)
    desc = RunDescription(protocol=protocol, parameters=dict(parameters or {}))
    with RunWriter(path, desc, daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        for a in range(0, t_frames.shape[0], 64):
            tt = t_frames[a:a + 64]
            k = np.clip(np.searchsorted(res.t_s, tt), 0, res.t_s.shape[0] - 1)
            imgs = np.stack([
                renderer.render(float(res.fn_N[i]), res.p_tables[int(res.stage[i])],
                                res.element_mode[i] != 0, int(res.stage[i]))
                for i in k])
            w.append_frames(imgs, tt, np.arange(a, a + tt.shape[0]))
    return path
