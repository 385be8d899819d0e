"""``storage.min_free_bytes`` is the reserve every run keeps (it was ignored: the runner kept the
built-in 64 MiB whatever the configuration said)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from experiments.runner import get_protocol
from rigctl.config.loader import parse_config
from rigctl.rigs import open_rig
from rigctl.storage.errors import StorageError

SHORT_NLRE = {"repetitions": "1", "peak_N": "50", "dwell_s": "0.1", "interval_s": "0.5"}


def test_the_configured_reserve_is_kept_by_the_run(tmp_path: Path) -> None:
    config = parse_config(f"[storage]\nmin_free_bytes = {2**60}\n")  # more than any disk
    out = tmp_path / "never.h5"
    with open_rig("sim", config, speed=math.inf) as rig:
        runner = rig.runner(get_protocol("nlre"), SHORT_NLRE, out=out, camera=False)
        assert runner.min_free_bytes == 2**60
        z0 = rig.devices.normal_stage.position_m()
        with pytest.raises(StorageError, match=r"not enough free space: .* plus 1099511627776\.0 "
                                               r"MiB in reserve"):
            runner.run()
        assert rig.devices.normal_stage.position_m() == z0  # refused before any motion
    assert not out.exists()


def test_the_dry_run_refuses_with_the_configured_reserve(tmp_path: Path, capsys) -> None:
    from rigctl.cli.main import main

    cfg = tmp_path / "rig.toml"
    cfg.write_text(f"[storage]\nmin_free_bytes = {2**60}\n", encoding="utf-8")
    code = main(["run", "nlre", "--config", str(cfg), "--dry-run", "--no-camera",
                 "--out", str(tmp_path / "x.h5"), *[f"--param={k}={v}" for k, v in SHORT_NLRE.items()]])
    err = capsys.readouterr().err
    assert code == 2
    assert "storage.min_free_bytes" in err and "not enough" in err
