"""The split of the series stiffness between drive spring and interface, where the data do not
read it (data_scale.split_guessed, search_space.build_space): the interface stiffness Kts is then
a spread coordinate like the mass, over K_eff (1 + Kts/K0) for the ratio's plausible interval,
with K0 moved to keep the series stiffness the loading ramps read and Kt0 in proportion
(docs/identification.md, "Starting values from the data")."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.records.rig_description import RigDescription
from rigctl.workbench import search_space
from rigctl.workbench.data_scale import STIFF_CAP, DataScale, split_guessed
from rigctl.workbench.data_start import campaign_scale
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search_space import build_space
from tests.workbench.synth import light_rig_tlre

SCALE = DataScale(fn_N=2.0, v_m_per_s=1e-5, mu_peak=0.3, mu_trough=0.2, mu_first=0.3,
                  k_eff_N_per_m=1e3, k_stick_N_per_m=5e3, stick_s=1.0)


def test_a_resolved_stick_stiffness_reads_the_split():
    assert split_guessed(SCALE) is None


def test_an_unresolved_give_leaves_either_stiffness_the_softer():
    assert split_guessed(dataclasses.replace(SCALE, k_stick_N_per_m=math.inf)) == (
        1.0 / STIFF_CAP, STIFF_CAP)


def test_without_delta_the_split_is_not_spread():
    # no feature reads the interface's give: the preset's ratio is kept, not searched
    assert split_guessed(dataclasses.replace(SCALE, delta_measured=False,
                                             k_stick_N_per_m=math.nan)) is None
    assert split_guessed(dataclasses.replace(SCALE, k_stick_N_per_m=math.nan)) is None


def test_no_split_without_a_usable_scale():
    assert split_guessed(dataclasses.replace(SCALE, k_eff_N_per_m=math.nan)) is None


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    """Another lab's record: a light rig, no rig description (every stiffness fitted)."""
    ds = prepare_dataset(light_rig_tlre(c0_N_s_per_m=0.6))
    return dataclasses.replace(ds, rig=RigDescription())


def _space(dataset: Dataset, k_stick: float, monkeypatch: pytest.MonkeyPatch
           ) -> tuple[search_space.SearchSpace, DataScale]:
    scale = dataclasses.replace(campaign_scale(dataset), k_stick_N_per_m=k_stick)
    monkeypatch.setattr(search_space, "campaign_scale", lambda _ds: scale)
    choice = ModelChoice("paper")
    return build_space(dataset, choice, choice, False), scale


def test_an_unresolved_split_spreads_kts_over_the_ratio_interval(dataset, monkeypatch):
    space, _ = _space(dataset, math.inf, monkeypatch)
    names = [fp.name for fp in space.free]
    i0, i1, j = (names.index(n) for n in ("k0_N_per_m", "kts_N_per_m", "kt0_N_per_m"))
    assert space.series == (i0, i1)
    assert space.spread[i1] == pytest.approx((-math.log(STIFF_CAP), math.log(STIFF_CAP)))
    # Kts = K_eff (1 + Kts/K0) spans K_eff (1 + 1/1000) to K_eff (1 + 1000)
    assert space.std[i1] == pytest.approx(0.25 * math.log((1.0 + STIFF_CAP)
                                                          / (1.0 + 1.0 / STIFF_CAP)))
    assert space.follows[j] == (i1, 1.0)
    assert i0 not in space.spread  # K0 follows the series, it is not drawn


def test_a_resolved_split_is_not_spread(dataset, monkeypatch):
    space, _ = _space(dataset, 3.0 * campaign_scale(dataset).k_eff_N_per_m, monkeypatch)
    names = [fp.name for fp in space.free]
    assert space.series is None
    assert names.index("kts_N_per_m") not in space.spread


def test_spread_points_keep_the_series_stiffness_and_the_interface_ratio(dataset, monkeypatch):
    space, _ = _space(dataset, math.inf, monkeypatch)
    names = [fp.name for fp in space.free]
    i0, i1, j = (names.index(n) for n in ("k0_N_per_m", "kts_N_per_m", "kt0_N_per_m"))
    x0 = space.vector(ModelChoice("paper"))
    v0 = space.values(x0)
    series0 = 1.0 / v0["k0_N_per_m"] + 1.0 / v0["kts_N_per_m"]
    points = space.sobol_points(x0, sorted(space.spread), 16, seed=1)
    ratios = sorted(space.values(x)["kts_N_per_m"] / space.values(x)["k0_N_per_m"]
                    for x in points)
    # ln(Kts/K0) evenly over +-ln 1000: as many draws with the interface the softer as the stiffer
    assert ratios[0] < 0.01 and ratios[-1] > 100.0
    assert sum(r < 1.0 for r in ratios) == len(ratios) // 2
    for x in points:
        v = space.values(x)
        assert 1.0 / v["k0_N_per_m"] + 1.0 / v["kts_N_per_m"] == pytest.approx(series0)
        assert v["kt0_N_per_m"] / v["kts_N_per_m"] == pytest.approx(
            v0["kt0_N_per_m"] / v0["kts_N_per_m"])
        others = [k for k in range(space.dim) if k not in (i0, i1, j, *space.spread,
                                                           *space.follows)]
        assert np.array_equal(x[others], x0[others])


def test_a_stated_drive_spring_leaves_no_split_to_spread(dataset, monkeypatch):
    scale = dataclasses.replace(campaign_scale(dataset), k_stick_N_per_m=math.inf)
    monkeypatch.setattr(search_space, "campaign_scale", lambda _ds: scale)
    stated = dataclasses.replace(dataset, rig=RigDescription(fixed={"k0_N_per_m": 500.0}))
    choice = ModelChoice("paper")
    space = build_space(stated, choice, choice, False)
    assert space.series is None
    assert all(fp.name != "kts_N_per_m" or i not in space.spread
               for i, fp in enumerate(space.free))
