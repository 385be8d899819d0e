"""K(i) = dFt/d(delta) in stick is read from slopes in time, so a post-slip ringing that lasts
into the loading ramp does not bias it (workbench.md, "Starting values from the data")."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.dataset import prepare_dataset
from rigctl.workbench.fitting import campaign_scale

# a light slider on a soft drive with 2 % damping: it rings at 34 Hz, decaying at 2.3 /s, into
# the loading ramp of the next stick (about 1 s long); Ft and delta swing in opposition in that
# ringing (dFt = -K0 d(delta)), which a regression of delta on Ft read as a stiffness 1.45 times
# Kts (7 times at 1 % damping)
RIG = {"k0_N_per_m": 1.9e3, "kts_N_per_m": 4.1e3, "m_kg": 0.13, "c0_N_s_per_m": 0.6,
       "mu_s": 0.39, "mu_k": 0.29, "mu_smax": 0.45, "kt0_N_per_m": 6.5e3, "n_elements": 29}


@pytest.fixture(scope="module")
def ringing_rig():
    runs = simulate_campaign(build_model("paper", params=RIG), "tlre", seed=3,
                             sample_rate_hz=3450.0, fn_N=70.0, velocity_m_s=7.4e-3,
                             duration_scale=0.5)
    return prepare_dataset(runs)


def test_k_i_reads_the_interface_stiffness_through_a_lasting_ringing(ringing_rig):
    k_i = np.concatenate([r.events.features["k_stick_N_per_m"][r.events.stage == 1]
                          for r in ringing_rig.runs])
    k_i = k_i[np.isfinite(k_i)]
    assert k_i.size >= 5
    # every stick, not only the median: the ringing's phase differs from slip to slip
    assert np.all(np.abs(k_i / RIG["kts_N_per_m"] - 1.0) < 0.1), k_i
    assert campaign_scale(ringing_rig).k_stick_N_per_m == pytest.approx(RIG["kts_N_per_m"],
                                                                         rel=0.05)
