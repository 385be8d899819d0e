"""A stick cut short by a velocity step: its ramp features come from a few dozen samples.

The campaign's scatter of loading rates and stick stiffnesses is set by full sticks (thousands of
samples, 0.5 %); the first stick after a step down to a slow velocity may last 80 ms, where the
white noise alone makes its rate uncertain by tens of per cent and attenuates its fitted
compliance (Ft is noisy too). Measured in the campaign's scatter, that one slip made the
generating model score 49 on a velocity-step campaign (docs/reading-records.md, "Short windows").
"""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import Drive, Simulator, build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.evaluate import evaluate

PARAMS = {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
          "mu_smax": 0.21}
FAST, SLOW = 5e-5, 5e-6
LEAD_S = 0.008
"""The step comes this long before a fast slip: the stick then ends after the 0.4 um of loading
left, 80 ms into the slow phase."""


def _step_before_a_slip() -> list[tuple[float, float]]:
    """Slide fast, then step down to slow LEAD_S before what would be the 6th fast slip."""
    sim = Simulator(build_model("paper", params=PARAMS), sample_rate_hz=1024.0)
    res = sim.run(Drive.constant(300.0, FAST, 12.0), noise=False, record_elements=False)
    drops = np.flatnonzero(np.diff(res.ft_N) < -2.0)
    starts = drops[np.concatenate([[True], np.diff(drops) > 10])]
    t_step = float(res.t_s[starts[5]]) - LEAD_S
    return [(t_step, FAST), (25.0, SLOW)]


@pytest.fixture(scope="module")
def stepped() -> Dataset:
    model = build_model("paper", params=PARAMS)
    res = Simulator(model, sample_rate_hz=1024.0).run(
        Drive.segments(300.0, _step_before_a_slip()), noise=True, seed=11, record_elements=False)
    run = res.to_measured()
    run.source = "stepped"
    return prepare_dataset([run])


def test_the_short_stick_carries_its_own_uncertainty(stepped: Dataset) -> None:
    ev = stepped.runs[0].events
    first_slow = int(np.flatnonzero(ev.first_in_segment() & (ev.segment == 1))[0])
    # it ends about 80 ms into the slow phase (its rate is read from ~40 samples)
    assert ev.t_drop_s[first_slow] - stepped.runs[0].drive.t_s[1] < 0.12
    se = ev.se["rate_N_per_s"]
    assert se[first_slow] > 20 * stepped.sigma["rate_N_per_s"]
    sig = stepped.event_sigma(0, "rate_N_per_s")
    assert sig[first_slow] == pytest.approx(se[first_slow])
    # full sticks keep the campaign scatter
    full = np.flatnonzero(~ev.first_in_segment())
    assert np.all(sig[full] == pytest.approx(stepped.sigma["rate_N_per_s"]))
    # its stiffness is either not read (force range within the noise) or read unbiased
    k = ev.features["k_stick_N_per_m"]
    if np.isfinite(k[first_slow]):
        assert k[first_slow] == pytest.approx(np.nanmedian(k[full]), rel=0.1)


def test_the_generating_model_is_within_the_scatter(stepped: Dataset) -> None:
    e = evaluate(stepped, build_model("paper", params=PARAMS)).score
    assert e.error < 1.5, e.feature_error
    # and a wrong model is not: mu_k 3 % off
    wrong = evaluate(stepped, build_model("paper", params={**PARAMS, "mu_k": 0.1236})).score
    assert wrong.error > 3.0, wrong.feature_error
