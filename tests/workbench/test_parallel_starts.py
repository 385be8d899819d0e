"""On another rig's data identify_model fits its two starts at once in worker processes (workers >
1), ending where it ends fitting them one after the other."""

from __future__ import annotations

import os

import pytest

from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import fitting
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from tests.workbench.synth import another_rig_record

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


@pytest.fixture(scope="module")
def dataset():
    return prepare_dataset([another_rig_record(20.0, 100.0, 2.0, source="r100.csv")])


def _pid_fits(monkeypatch):
    """Each start's fit stood in for by its start, its message the process that fitted it."""

    def fit_from(dataset, choice, e_start, free, fns, *, free_dynamics, max_nfev,
                 with_uncertainty):
        return FitResult(choice, e_start, {}, tuple(fp.name for fp in free),
                         message=f"pid {os.getpid()}")

    monkeypatch.setattr(fitting, "_fit_from", fit_from)
    monkeypatch.setattr(fitting, "_dynamics_to_fit", lambda dataset, have: [])


def test_the_two_starts_are_fitted_in_two_worker_processes(dataset, monkeypatch):
    _pid_fits(monkeypatch)
    starts = []
    real = fitting._fit_starts

    def spy(tasks, workers):
        out = real(tasks, workers)
        starts.append([r.message for r in out])
        return out

    monkeypatch.setattr(fitting, "_fit_starts", spy)
    fitting.identify_model(dataset, ModelChoice("paper"), workers=2)
    fitting.identify_model(dataset, ModelChoice("paper"), workers=1)
    (at_once, alone) = starts
    here = f"pid {os.getpid()}"
    assert len(at_once) == 2 and here not in at_once and at_once[0] != at_once[1]
    assert alone == [here, here]


def test_at_once_the_fit_ends_as_one_after_the_other(dataset):
    alone = fitting.identify_model(dataset, ModelChoice("paper"), with_uncertainty=False)
    at_once = fitting.identify_model(dataset, ModelChoice("paper"), with_uncertainty=False,
                                     workers=2)
    assert at_once.error == alone.error and at_once.choice == alone.choice
    assert at_once.free == alone.free


def test_a_start_whose_worker_failed_is_fitted_here(dataset, monkeypatch):
    """A failure in a worker is not lost: the start is fitted again in this process, which raises
    what the fit raises or returns its end."""
    _pid_fits(monkeypatch)
    monkeypatch.setattr(fitting, "run_tasks",
                        lambda fn, tasks, **kw: [fitting.TaskFailed("worker died")] * len(tasks))
    res = fitting.identify_model(dataset, ModelChoice("paper"), workers=2)
    assert res.message == f"pid {os.getpid()}"
