"""Draw the contact-image figures of docs/analysis.md from a simulated run with camera frames.

Run from the repository root: ``python docs/img/contact_figures.py``. The run: the paper's model
(``paper``: stress_evolution) loaded to 300 N in 3 s, 2 s at rest, then 25 s of sliding at 10 um/s,
with sensor noise; frames of the simulated camera (640 x 480, 30 Hz) rendered from the model's contact
state (tests/analysis/contact_sim.py). Writes docs/img/contact_*.png.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rigctl.analysis import figures_contact  # noqa: E402
from rigctl.analysis.pipeline import analyse_run  # noqa: E402
from rigctl.analysis.surface_psd import surface_psd  # noqa: E402
from rigctl.model import Drive, Simulator, build_model  # noqa: E402
from rigctl.model.noise import NoiseModel  # noqa: E402
from sim_devices.contact_image import CameraOptics, ContactImageRenderer  # noqa: E402
from tests.analysis.contact_sim import write_with_frames  # noqa: E402

OUT = ROOT / "docs" / "img"


def main() -> None:
    optics = CameraOptics(width_px=640, height_px=480)
    t = np.array([0.0, 3.0, 5.0, 30.0])
    x = np.array([0.0, 0.0, 0.0, 25 * 1e-5])
    fn = np.array([0.0, 300.0, 300.0, 300.0])
    res = Simulator(build_model("paper")).run(Drive(t, x, fn))
    NoiseModel().apply(res, np.random.default_rng(1))
    with tempfile.TemporaryDirectory() as tmp:
        path = write_with_frames(Path(tmp) / "sim.h5", res, res.to_measured(), 30.0, optics)
        ra = analyse_run(path)
    ca = ra.contact
    assert ca is not None, ra.contact_absent
    rec = ra.mechanics.passes[0]
    pc = ca.passes[0]
    names = [
        figures_contact.isum_figure(ca, OUT, "contact_isum.png"),
        figures_contact.fig7(ca, pc, rec, OUT, "contact_p_xt.png"),
        figures_contact.fig13(pc, OUT, "contact_p_bins.png"),
        figures_contact.fig9(pc, OUT, "contact_csi.png"),
    ]
    r = ContactImageRenderer(optics)
    psd = surface_psd(r.height_m, r.pixel_m)
    names.append(figures_contact.psd_figure(psd, OUT, "contact_surface_psd.png", r.height_m,
                                            r.pixel_m))
    for c in pc.csi:
        print(c.stage, c.ft_N, {k: round(v, 3) for k, v in c.props.proportions.items()})
    print("Im:", [round(m.im) for m in pc.im])
    print("Sq from PSD", psd.sq_m, "anisotropy", psd.anisotropy)
    print("wrote", ", ".join(names))


if __name__ == "__main__":
    main()
