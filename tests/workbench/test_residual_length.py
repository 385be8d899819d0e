"""The residual vector's length is the data's (metrics.residual_length), and a point whose model
cannot be run gets its failure penalty without another model run (identify.Objective).

A model run to learn the length, unbounded and without a time limit, once held both workers of a
held-out search for over 17 minutes: the pool's model there chattered through slips the record
cannot show."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import rigctl.workbench.identify as identify_module
from rigctl.errors import SimulationError
from rigctl.io.load import load_runs
from rigctl.model import Drive, NoiseModel, Simulator, build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.storage import RunReader
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import Objective, free_params
from rigctl.workbench.metrics import residual_length
from rigctl.workbench.model_choice import ModelChoice
from tests.analysis.contact_sim import write_with_frames

PAPER = ModelChoice("paper")
ENS = Path(__file__).resolve().parents[1] / "data" / "real" / "ens_k168_velocity_campaign"


def _campaign(protocol: str) -> Dataset:
    scale = 1.0 if protocol == "force_sweep" else 0.3  # a slip at every load
    return prepare_dataset(simulate_campaign(build_model("paper"), protocol, seed=3,
                                             duration_scale=scale))


def _lengths(ds: Dataset) -> set[int]:
    """The residual's length for the preset and for models far from it."""
    out = set()
    for values in ({}, {"mu_k": 0.05}, {"mu_s": 0.3, "k0_N_per_m": 3e5}):
        sc = evaluate(ds, PAPER.with_values(values)).score
        out.add(int(sc.vector.shape[0]))
        # the layout that sizes the vector also weighs it: |v|^2 = n_features * E^2
        assert float(sc.vector @ sc.vector) == pytest.approx(
            len(sc.feature_error) * sc.error**2, rel=1e-9)
    return out


@pytest.mark.parametrize("protocol", ["velocity_steps", "slide_hold_slide", "force_sweep", "tlre"])
def test_the_length_is_the_data_s_whatever_the_model(protocol: str) -> None:
    ds = _campaign(protocol)
    assert _lengths(ds) == {residual_length(ds)}


def test_the_length_counts_the_image_features(tmp_path: Path) -> None:
    # load 0 -> 300 N in 1 s, rest 2 s, slide 200 um at 10 um/s, release under load, apart (the
    # TLRE of tests/workbench/test_image_features.py: an initial and a stable stage in frames)
    drive = Drive(np.array([0.0, 1.0, 3.0, 23.0, 24.0, 25.0]),
                  np.array([0.0, 0.0, 0.0, 2e-4, 2e-4, 2e-4]),
                  np.array([0.0, 300.0, 300.0, 300.0, 0.0, 0.0]))
    res = Simulator(build_model("paper")).run(drive)
    NoiseModel().apply(res, np.random.default_rng(1))
    path = write_with_frames(tmp_path / "tlre.h5", res, res.to_measured(), protocol="tlre")
    with RunReader(path) as reader:
        ds = prepare_dataset([reader.to_measured()])
    assert ds.runs[0].image is not None, ds.notes
    assert _lengths(ds) == {residual_length(ds)}


def test_the_length_of_a_real_record() -> None:
    ds = prepare_dataset(load_runs([ENS / "k168_v1100.csv"]))
    assert _lengths(ds) == {residual_length(ds)}


def test_a_point_that_cannot_be_run_costs_one_attempt(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first point an objective sees fails (its model past its time limit): its penalty has
    the data's length, and no other model run is made to learn it."""
    ds = _campaign("velocity_steps")
    calls: list[bool] = []

    def failing(dataset, choice, **kw):  # type: ignore[no-untyped-def]
        calls.append(kw.get("bounded", False))
        raise SimulationError("the run passed its time limit")

    obj = Objective(ds, PAPER, free_params(PAPER, rig=ds.rig))
    monkeypatch.setattr(identify_module, "evaluate", failing)
    vec = obj(np.zeros(len(obj.free)))
    assert calls == [True]  # the bounded attempt only
    assert vec.shape == (residual_length(ds),)
    assert obj.failed(np.zeros(len(obj.free)))
    assert float(vec @ vec) == pytest.approx(obj.failed_norm**2)
