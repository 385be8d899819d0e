"""`rigctl export`, `rigctl import`, `rigctl info`: happy paths and one-line errors (exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rigctl.cli.main import main
from rigctl.io.csv_format import write_csv
from rigctl.storage import RunReader
from tests.io.conftest import make_run


@pytest.fixture
def csv_file(tmp_path: Path) -> Path:
    path = tmp_path / "in.csv"
    write_csv(path, make_run(3000))
    return path


def test_import_info_export_round_trip(
    tmp_path: Path, csv_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run_file = tmp_path / "run.h5"
    assert main(["import", str(csv_file), "--out", str(run_file), "--notes", "lab A"]) == 0
    with RunReader(run_file) as r:
        assert (r.protocol, r.parameters, r.status) == ("import", {"source": "in.csv"}, "completed")
    capsys.readouterr()

    assert main(["info", str(run_file)]) == 0
    out = capsys.readouterr().out
    for expected in (
        "protocol  import",
        "status    completed",
        "3000 at 1024 Hz",
        "ft_N [N]",
        "temp_C [degC]",
        "dropped   0 samples, 0 frames",
        "notes     lab A",
    ):
        assert expected in out, out

    assert main(["info", str(run_file), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_samples"] == 3000 and summary["channels"]["d1_m"] == "m"

    back = tmp_path / "back.csv"
    assert main(["export", str(run_file), "--csv", str(back)]) == 0
    # the same bytes, plus the provenance lines of the run file (# run.protocol: import, ...)
    lines = back.read_bytes().splitlines(keepends=True)
    provenance = [ln for ln in lines if ln.startswith(b"# run.")]
    assert b"# run.protocol: import\n" in provenance and b"# run.status: completed\n" in provenance
    assert b"".join(ln for ln in lines if not ln.startswith(b"# run.")) == csv_file.read_bytes()


def test_info_accepts_a_csv(csv_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(csv_file)]) == 0
    out = capsys.readouterr().out
    assert "3000 at 1024 Hz" in out and "operator  A. Tester" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["info", "{tmp}/absent.h5"], "absent.h5: no such file"),
        (["info", "{tmp}/run.txt"], "expected a .h5 or .hdf5 or .nxs file"),
        (["export", "{csv}", "--csv", "{tmp}/x.csv"], "expected a .h5"),
        (["import", "{tmp}/bad.csv", "--out", "{tmp}/x.h5"], "bad.csv, line 3, column 'fn_N'"),
        (["import", "{csv}", "--out", "{tmp}/exists.h5"], "already exists; use --force"),
        (["import", "{csv}", "--out", "{tmp}/no/dir/x.h5"], "does not exist"),
        (["export", "{tmp}/exists.h5", "--csv", "{tmp}/no/dir/x.csv"], "does not exist"),
        (["export", "{tmp}/exists.h5"], "required: --csv"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, csv_file: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    (tmp_path / "bad.csv").write_text("t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m\n0,0,0,0,0,0\n0.1,0,oops,0,0,0\n")
    (tmp_path / "run.txt").write_text("x")
    assert main(["import", str(csv_file), "--out", str(tmp_path / "exists.h5")]) == 0
    capsys.readouterr()
    before = sorted(p.name for p in tmp_path.iterdir())
    args = [a.format(tmp=tmp_path, csv=csv_file) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("rigctl: error: ") and err.count("\n") == 1, err
    assert message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing half-written


def test_force_replaces_an_imported_run(tmp_path: Path, csv_file: Path) -> None:
    out = tmp_path / "run.h5"
    assert main(["import", str(csv_file), "--out", str(out)]) == 0
    small = tmp_path / "small.csv"
    write_csv(small, make_run(10))
    assert main(["import", str(small), "--out", str(out), "--force"]) == 0
    with RunReader(out) as r:
        assert r.n_samples == 10


def test_info_says_when_a_run_was_not_closed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rigctl.storage import RunDescription, RunWriter
    from tests.storage.conftest import block

    path = tmp_path / "open.h5"
    w = RunWriter(path, RunDescription(protocol="tlre"))
    try:
        w.append_daq(block(0, 64))
        w.flush()
        assert main(["info", str(path)]) == 0
    finally:
        w.close()
    out = capsys.readouterr().out
    assert "status    running (still being written, or the writer stopped" in out
    assert "64 at 1024 Hz" in out


def test_info_json_is_valid_json_where_a_figure_is_undefined(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A one-sample record has no sample rate (NaN); the JSON says null (strict parsers refuse NaN)."""
    one = tmp_path / "one.csv"
    one.write_text("t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m\n0,0,0,0,0,0\n")
    assert main(["info", str(one), "--json"]) == 0

    def refuse(name: str) -> None:
        raise ValueError(f"{name} in JSON")

    summary = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert summary["sample_rate_hz"] is None and summary["n_samples"] == 1


def test_export_keeps_provenance_and_a_killed_run_is_not_reimported_completed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rigctl.io.csv_format import read_csv
    from rigctl.storage import RunDescription, RunWriter
    from tests.storage.conftest import block

    path = tmp_path / "killed.h5"
    w = RunWriter(path, RunDescription(protocol="tlre"))
    try:
        w.append_daq(block(0, 2048))
        w.flush()
        # exported while never closed: as a run killed by SIGKILL looks
        assert main(["export", str(path), "--csv", str(tmp_path / "k.csv")]) == 0
    finally:
        w.close()
    meta = read_csv(tmp_path / "k.csv").metadata
    assert meta["run.protocol"] == "tlre" and meta["run.status"] == "running"
    assert "rigctl" in meta["run.software"]
    assert main(["import", str(tmp_path / "k.csv"), "--out", str(tmp_path / "re.h5")]) == 0
    assert "imported as aborted" in capsys.readouterr().err
    with RunReader(tmp_path / "re.h5") as r:
        assert r.status == "aborted"
        assert "not closed" in r.summary().error
