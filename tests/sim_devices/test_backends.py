"""Building and shutting down whole simulated rigs, and ``rigctl devices check``."""

from __future__ import annotations

import os
import threading

import pytest

from rigctl.cli.main import main
from sim_devices.backends import DEVICE_NAMES, build_sim_rig, open_sim_rig


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.mark.parametrize("backend", ["sim", "sim-wire"])
def test_everything_started_is_stopped(backend: str) -> None:
    threads, fds = threading.active_count(), open_fds()
    with open_sim_rig(backend, speed=5.0) as sim:
        assert [name for name, _ in sim.devices.items()] == list(DEVICE_NAMES)
        assert set(sim.faults) == set(DEVICE_NAMES)
        assert threading.active_count() > threads  # the rig's clock (and servers) run
        sim.devices.tangential_stage.status()
    assert threading.active_count() == threads
    assert open_fds() == fds  # ptys, sockets and buses closed


def test_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown simulated backend"):
        build_sim_rig("real")


def test_devices_check_on_both_simulated_backends(capsys: pytest.CaptureFixture[str]) -> None:
    for backend in ("sim", "sim-wire"):
        assert main(["devices", "check", "--backend", backend]) == 0
        out = capsys.readouterr().out
        for name in DEVICE_NAMES:
            assert f"ok    {name}" in out
        assert "all devices answered" in out


def test_devices_check_real_needs_a_configuration(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("RIGCTL_CONFIG", raising=False)
    assert main(["devices", "check", "--backend", "real"]) == 2
    assert "needs a rig configuration" in capsys.readouterr().err


def test_devices_check_names_the_devices_that_fail(
    tmp_path: os.PathLike[str], capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "rig.toml"  # type: ignore[operator]
    config.write_text(
        "[rig]\nbackend = \"real\"\n"
        "[tangential_stage]\nport = 1\ntimeout_s = 0.05\nretries = 0\n"
        "[normal_stage]\nport = 1\ntimeout_s = 0.05\nretries = 0\n"
        "[daq]\nchannel = \"nobody-listens\"\ncommand_timeout_s = 0.05\ncommand_retries = 0\n"
        "[probes.d1]\nurl = \"loop://\"\ntimeout_s = 0.05\nretries = 0\n"
        "[probes.d2]\nurl = \"/nonexistent/tty\"\n"
        "[camera]\nsource = \"/nonexistent/video.avi\"\n"
    )
    assert main(["devices", "check", "--config", str(config)]) == 1
    captured = capsys.readouterr()
    failing = captured.err.strip().splitlines()[-1]
    assert failing.startswith("rigctl: devices failing:")
    for name in DEVICE_NAMES:
        assert name in failing
        assert f"FAIL  {name}" in captured.out
