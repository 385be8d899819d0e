"""Run statuses and diagnosis verdicts are enums in the code and their strings in files and JSON."""

from __future__ import annotations

import json

import h5py
import pytest

from rigctl.status import RunStatus
from rigctl.storage import RunWriter
from rigctl.storage.layout import FINAL_STATUSES, DaqLayout, RunDescription
from rigctl.workbench.ranking import Verdict, VerdictKind


def test_run_status_values_are_the_file_strings() -> None:
    assert [s.value for s in RunStatus] == ["running", "completed", "aborted", "failed"]
    assert RunStatus.RUNNING not in FINAL_STATUSES
    assert json.dumps({"status": RunStatus.ABORTED}) == '{"status": "aborted"}'


@pytest.mark.parametrize("status", FINAL_STATUSES)
def test_the_writer_stores_the_status_text(tmp_path, status: RunStatus) -> None:
    path = tmp_path / "run.h5"
    writer = RunWriter(path, RunDescription(protocol="test"), DaqLayout(sample_rate_hz=1024.0))
    assert writer.status is RunStatus.RUNNING
    writer.close(status, None if status is RunStatus.COMPLETED else "why")
    assert writer.status is status
    with h5py.File(path, "r") as f:
        assert f["entry/status"][()].decode() == status.value


def test_the_writer_refuses_a_status_that_is_not_final(tmp_path) -> None:
    writer = RunWriter(tmp_path / "run.h5", RunDescription(protocol="test"),
                       DaqLayout(sample_rate_hz=1024.0))
    with pytest.raises(ValueError, match="completed, aborted, failed"):
        writer.close(RunStatus.RUNNING)
    writer.close()


@pytest.mark.parametrize(
    ("text", "kind"),
    [("none", VerdictKind.NONE), ("indistinguishable", VerdictKind.INDISTINGUISHABLE),
     ("stribeck", VerdictKind.EFFECT)],
)
def test_verdict_kind(text: str, kind: VerdictKind) -> None:
    v = Verdict(text, [], None)
    assert v.kind is kind
    assert json.dumps({"verdict": v.verdict}) == json.dumps({"verdict": text})
