"""`rigctl bench engine --json --quick` prints one JSON object with the documented keys."""

from __future__ import annotations

import json

import pytest

from rigctl.cli.main import main


@pytest.mark.slow
def test_bench_engine_quick_json(capsys):
    assert main(["bench", "engine", "--json", "--quick"]) == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("realtime_factor_n10", "realtime_factor_n100", "speedup_vs_rk45"):
        assert isinstance(data[key], float | int)
        assert data[key] > 0
    assert isinstance(data["max_force_error_N"], float | int)
    assert data["max_force_error_N"] >= 0
