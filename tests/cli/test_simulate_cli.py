"""`rigctl simulate`: the run it writes, and one-line errors with exit code 2 for bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.cli.main import main
from rigctl.data import REQUIRED_COLUMNS
from rigctl.io.csv_format import read_csv


@pytest.mark.slow
def test_simulate_writes_exchange_csv_and_plot(tmp_path, capsys):
    out = tmp_path / "run.csv"
    png = tmp_path / "run.png"
    rc = main(["simulate", "--fn", "300", "--velocity", "1e-5", "--duration", "20",
               "--out", str(out), "--plot", str(png)])
    assert rc == 0
    run = read_csv(out)
    assert run.n_samples == 20 * 1024 + 1
    assert run.sample_rate_hz == pytest.approx(1024.0)
    assert list(run.columns())[: len(REQUIRED_COLUMNS)] == list(REQUIRED_COLUMNS)
    assert run.ft_N.max() == pytest.approx(60.0, rel=0.03)
    assert np.all(run.fn_N == 300.0)
    assert png.stat().st_size > 10_000
    assert "slips" in capsys.readouterr().out


def test_segments_effects_and_seeded_noise_are_reproducible(tmp_path):
    args = ["simulate", "--segments", "5:1e-5,2:0,5:3e-5", "--effect", "rate_state:b=0.006",
            "--effect", "sensor_dynamics", "--param", "mu_k=0.09", "--noise", "--seed", "3"]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main([*args, "--out", str(a)]) == 0
    assert main([*args, "--out", str(b)]) == 0
    ra, rb = read_csv(a), read_csv(b)
    assert np.array_equal(ra.ft_N, rb.ft_N)
    # the hold segment: stage does not move
    hold = (ra.t_s > 5.05) & (ra.t_s < 6.95)
    assert np.ptp(ra.x_stage_m[hold]) == 0.0


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--effect", "nope"],
        ["simulate", "--param", "nonsense=1"],
        ["simulate", "--param", "mu_s=nan"],
        ["simulate", "--duration", "-5"],
        ["simulate", "--duration", "nan"],
        ["simulate", "--fn", "900"],
        ["simulate", "--segments", "5:1e-5,oops"],
        ["simulate", "--effect", "rate_state:b=0.9"],
        ["simulate", "--bogus-flag"],
    ],
)
def test_bad_arguments_exit_2_with_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rigctl: error:")


def test_broken_effect_file_is_named(tmp_path, capsys):
    bad = tmp_path / "broken_effect.py"
    bad.write_text("def oops(:\n")
    assert main(["simulate", "--duration", "1", "--effect-file", str(bad)]) == 2
    assert "broken_effect.py" in capsys.readouterr().err
