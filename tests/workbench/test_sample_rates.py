"""Records sampled from 100 Hz to 20 kHz are read and fitted at their own scale.

At 100 Hz a stick cycle of 2 s has 200 samples and a slip falls between two of them; at 20 kHz the
post-slip ringing (about 220 Hz on this rig) is resolved sample by sample. The slips and the
friction levels and series stiffness must come out of both.
"""

from __future__ import annotations

import pytest

from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.compare import compare
from rigctl.workbench.model_choice import ModelChoice
from tests.workbench.synth import ANOTHER_RIG as R
from tests.workbench.synth import another_rig_record

KEFF = 1.0 / (1.0 / R["k0_N_per_m"] + 1.0 / R["kts_N_per_m"])


@pytest.mark.slow
@pytest.mark.timeout(1500)  # a full identification at 20 kHz: minutes on a 2-core machine
@pytest.mark.parametrize(("rate_hz", "duration_s", "cycle_s"), [(100.0, 60.0, 2.0),
                                                               (20_000.0, 6.0, 0.5)])
def test_a_record_of_another_rig_is_fitted_at_any_sample_rate(rate_hz: float, duration_s: float,
                                                              cycle_s: float) -> None:
    run = another_rig_record(duration_s, rate_hz, cycle_s, source=f"r{rate_hz:.0f}.csv")
    ds = prepare_dataset([run])
    expected = duration_s / cycle_s
    assert 0.8 * expected <= ds.n_events <= 1.1 * expected, ds.n_events
    cmp = compare([run], ModelChoice("paper"), dataset=ds, workers=2)
    v = cmp.fit.choice.values
    keff = 1.0 / (1.0 / v["k0_N_per_m"] + 1.0 / v["kts_N_per_m"])
    assert keff == pytest.approx(KEFF, rel=0.1)
    assert v["mu_s"] == pytest.approx(R["mu_s"], rel=0.05)
    assert v["mu_k"] == pytest.approx(R["mu_k"], rel=0.05)
    assert cmp.fit.error < 3.0
