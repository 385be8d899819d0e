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
