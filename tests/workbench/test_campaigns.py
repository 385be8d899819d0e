"""The campaign generator: protocols, noise, and which protocol reveals which effect."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import build_model, effect_names
from rigctl.records.dataset import prepare_dataset, protocols_present
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, PROTOCOLS, protocol_runs, simulate_campaign


def test_every_library_effect_has_a_revealing_protocol():
    assert set(PROTOCOL_FOR_EFFECT) == set(effect_names())
    assert set(PROTOCOL_FOR_EFFECT.values()) <= set(PROTOCOLS)


@pytest.mark.parametrize(("protocol", "present"), [
    ("force_sweep", "force sweep"),
    ("velocity_steps", "velocity steps"),
    ("slide_hold_slide", "slide-hold-slide"),
    ("long_run", "long run"),
])
def test_each_protocol_is_recognised_in_its_own_data(protocol, present):
    runs = simulate_campaign(build_model("paper"), protocol, seed=1)
    assert present in protocols_present(prepare_dataset(runs))


def test_noise_is_realistic_and_seeded():
    a = simulate_campaign(build_model("paper"), "tlre", seed=3, duration_scale=0.3)[0]
    b = simulate_campaign(build_model("paper"), "tlre", seed=3, duration_scale=0.3)[0]
    c = simulate_campaign(build_model("paper"), "tlre", seed=4, duration_scale=0.3)[0]
    assert np.array_equal(a.ft_N, b.ft_N) and not np.array_equal(a.ft_N, c.ft_N)
    quiet = simulate_campaign(build_model("paper"), "tlre", noise=False, duration_scale=0.3)[0]
    assert 0.02 < float(np.std(a.ft_N - quiet.ft_N)) < 0.2


def test_unknown_protocol_is_refused():
    with pytest.raises(ValueError, match="unknown protocol"):
        protocol_runs("spin_cycle")
