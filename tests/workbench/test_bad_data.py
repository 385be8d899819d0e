"""Bad data gets one clear line naming the file, from CSV campaigns and HDF5 run files alike.

Each case is written both ways and given to ``rigctl model compare`` and ``model diagnose``: NaN in
a required column, a run too short to hold a slip, a handful of samples, and a stage that never
moves. Exit code 2, one line on stderr, the file named and the problem said.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.cli.main import main
from rigctl.data import MeasuredRun
from rigctl.io.csv_format import write_csv
from rigctl.model import build_model
from rigctl.storage.convert import write_measured_run
from rigctl.workbench.campaigns import simulate_campaign


@pytest.fixture(scope="module")
def good_run() -> MeasuredRun:
    # 30 s at 10 um/s: the initial stage and a few stable cycles
    return simulate_campaign(build_model("paper"), "tlre", seed=41, duration_scale=0.5)[0]


def _write(run: MeasuredRun, folder: Path, stem: str, fmt: str) -> Path:
    path = folder / f"{stem}.{fmt}"
    if fmt == "csv":
        write_csv(path, run)
    else:
        write_measured_run(path, run)
    return path


def _put_nan(path: Path, column: str, sample: int) -> None:
    """Corrupt one value of a written file (the writers refuse NaN, as they should)."""
    if path.suffix == ".h5":
        with h5py.File(path, "r+") as f:
            f[f"entry/daq/{column}"][sample] = np.nan
        return
    lines = path.read_text().splitlines()
    header_at = next(i for i, line in enumerate(lines) if line.startswith("t_s"))
    names = lines[header_at].split(",")
    cells = lines[header_at + 1 + sample].split(",")
    cells[names.index(column)] = "nan"
    lines[header_at + 1 + sample] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.mark.parametrize("fmt", ["csv", "h5"])
@pytest.mark.parametrize("command", ["compare", "diagnose"])
def test_nan_is_named_with_file_and_column(good_run, tmp_path, capsys, fmt, command):
    path = _write(good_run, tmp_path, "with_nan", fmt)
    _put_nan(path, "ft_N", 700)
    err = _one_line_error(capsys, ["model", command, str(path)])
    assert "with_nan" in err and "ft_N" in err and "NaN" in err


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_a_run_too_short_to_contain_a_slip_is_refused(good_run, tmp_path, capsys, fmt):
    n = int(3.0 * good_run.sample_rate_hz)  # 3 s: still in the initial loading, no slip yet
    path = _write(_head(good_run, n), tmp_path, "three_seconds", fmt)
    err = _one_line_error(capsys, ["model", "compare", str(path)])
    assert "three_seconds" in err and "no slip" in err


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_a_handful_of_samples_is_refused(good_run, tmp_path, capsys, fmt):
    path = _write(_head(good_run, 40), tmp_path, "forty_samples", fmt)
    err = _one_line_error(capsys, ["model", "diagnose", str(path)])
    assert "forty_samples" in err and "too short" in err


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_a_stage_that_never_moves_is_refused(good_run, tmp_path, capsys, fmt):
    still = _head(good_run, good_run.n_samples)
    still.x_stage_m = np.full(still.n_samples, 1.25e-3) + np.random.default_rng(0).normal(
        0.0, 2e-9, still.n_samples)
    path = _write(still, tmp_path, "no_motion", fmt)
    err = _one_line_error(capsys, ["model", "compare", str(path)])
    assert "no_motion" in err and "stage does not move" in err and "x_stage_m" in err


def test_one_bad_run_in_a_campaign_folder_is_named(good_run, tmp_path, capsys):
    _write(good_run, tmp_path, "01_good", "csv")
    bad = _write(good_run, tmp_path, "02_bad", "csv")
    _put_nan(bad, "d1_m", 300)
    err = _one_line_error(capsys, ["model", "compare", str(tmp_path)])
    assert "02_bad" in err and "d1_m" in err


def _head(run: MeasuredRun, n: int) -> MeasuredRun:
    return MeasuredRun(
        t_s=run.t_s[:n].copy(), x_stage_m=run.x_stage_m[:n].copy(), fn_N=run.fn_N[:n].copy(),
        ft_N=run.ft_N[:n].copy(), d1_m=run.d1_m[:n].copy(), d2_m=run.d2_m[:n].copy(),
        source=run.source, metadata=dict(run.metadata),
    )
