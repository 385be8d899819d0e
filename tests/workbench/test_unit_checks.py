"""A column left in a lab's own unit (ms, um, kN) is named in the dataset's notes; the record is
still analysed, and a record in SI units gets no such note."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.records.unit_checks import UNIT_NOTE
from rigctl.workbench.campaigns import simulate_campaign


@pytest.fixture(scope="module")
def good_run() -> MeasuredRun:
    # 30 s at 10 um/s: the initial stage and a few stable cycles, 1024 Hz
    return simulate_campaign(build_model("paper"), "tlre", seed=41, duration_scale=0.5)[0]


def _unit_notes(run: MeasuredRun) -> list[str]:
    return [n for n in prepare_dataset([run]).notes if n.startswith(UNIT_NOTE)]


def test_a_record_in_si_units_gets_no_unit_note(good_run):
    assert _unit_notes(good_run) == []


@pytest.mark.parametrize(("change", "words"), [
    ({"t_s": 1e3}, ("t_s", "not ms")),  # 1024 Hz read as 1 Hz
    ({"x_stage_m": 1e6}, ("x_stage_m", "not um")),  # 10 um/s read as 10 m/s
    ({"ft_N": 1e-3}, ("ft_N", "0.000", "kN")),  # friction coefficient 2e-4
    ({"d1_m": 1e6, "d2_m": 1e6}, ("d1_m - d2_m", "not um")),  # the probes' um read as m
])
def test_a_column_in_another_unit_is_named(good_run, change, words):
    run = replace(good_run, **{k: getattr(good_run, k) * f for k, f in change.items()})
    notes = _unit_notes(run)
    assert len(notes) == 1, notes
    assert all(w in notes[0] for w in words), notes[0]


def test_both_forces_in_kn_are_not_a_unit_mistake(good_run):
    """The ratio of the forces is what is checked: a rig whose forces are both 1000 times smaller
    (an AFM-scale contact) is not suspected."""
    run = replace(good_run, ft_N=good_run.ft_N * 1e-3, fn_N=good_run.fn_N * 1e-3)
    assert _unit_notes(run) == []


def test_a_long_loaded_rest_before_a_short_slide_is_not_a_unit_mistake(good_run):
    """The friction ratio is read while the stage slides: a record that rests loaded (Ft near 0)
    for 20 times as long as it slides has a friction coefficient near 0 in 95 % of its loaded
    samples, and its forces are still both in newtons."""
    n = good_run.t_s.size
    dt = float(np.median(np.diff(good_run.t_s)))
    n_rest = 20 * n
    t_rest = good_run.t_s[0] - dt * np.arange(n_rest, 0, -1)
    rng = np.random.default_rng(3)
    fn0 = float(good_run.fn_N[0])
    run = MeasuredRun(
        t_s=np.concatenate([t_rest, good_run.t_s]),
        x_stage_m=np.concatenate([np.full(n_rest, good_run.x_stage_m[0]), good_run.x_stage_m]),
        fn_N=np.concatenate([fn0 + 0.01 * rng.standard_normal(n_rest), good_run.fn_N]),
        ft_N=np.concatenate([0.01 * rng.standard_normal(n_rest), good_run.ft_N]),
        d1_m=np.concatenate([np.full(n_rest, good_run.d1_m[0]), good_run.d1_m]),
        d2_m=np.concatenate([np.full(n_rest, good_run.d2_m[0]), good_run.d2_m]),
        metadata=dict(good_run.metadata), source="rest_then_slide")
    assert fn0 > 100.0  # loaded from the first sample: the rest counts as loaded
    assert _unit_notes(run) == []
    kn = replace(run, ft_N=run.ft_N * 1e-3)
    assert any("ft_N" in n for n in _unit_notes(kn))


@pytest.mark.slow
def test_the_report_lists_the_notes_on_the_data(good_run, tmp_path):
    """The HTML report carries what the command line prints about the data (here the unit to
    check), not only the fit."""
    from rigctl.workbench.compare import compare
    from rigctl.workbench.model_choice import ModelChoice
    from rigctl.workbench.report import write_compare_report

    run = replace(good_run, ft_N=good_run.ft_N * 1e-3)
    cmp = compare([run], ModelChoice("paper"), identify=False)
    page = write_compare_report(cmp, tmp_path / "report").read_text()
    assert "Notes on the data" in page
    assert f"{UNIT_NOTE} of" in page and "not one in kN or mN" in page
