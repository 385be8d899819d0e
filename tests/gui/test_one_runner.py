"""One way to build a run: the command line, the window's in-process worker and the run service
record the same metadata (the rig's stated mass and damping included) for the same run."""

from __future__ import annotations

import argparse
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from rigctl.config.loader import default_config
from rigctl.gui.run_panel import RunPanel
from rigctl.rigs import OpenRig
from rigctl.runservice.server import RunService
from rigctl.runservice.wire import Address, JobSpec
from rigctl.storage.reader import RunReader

SHORT_NLRE = {"repetitions": "1", "peak_N": "50", "dwell_s": "0.1", "interval_s": "0.5"}
"""About 13 s of rig time: a couple of seconds at speed max."""
TIMEOUT_MS = 60_000
PER_PATH = ("started_from", "run_service_pid")
"""Metadata that says which path started the run (and so differs between them)."""


@pytest.fixture
def signal_handlers() -> Iterator[None]:
    """``rigctl run`` installs its own SIGINT/SIGTERM/SIGUSR handlers; put pytest's back after."""
    kept = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1,
                                             signal.SIGUSR2)}
    yield
    for s, handler in kept.items():
        signal.signal(s, handler)


def cli_run(out: Path) -> dict[str, str]:
    from rigctl.cli.cmd_run import register

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(["run", "nlre", "--speed", "max", "--no-camera", "--out", str(out),
                              *(f"--param={k}={v}" for k, v in SHORT_NLRE.items())])
    assert args.func(args) == 0
    with RunReader(out) as r:
        return r.metadata


def panel_run(qtbot: object, rig: OpenRig, out: Path) -> dict[str, str]:
    panel = RunPanel(default_config(), "sim", rig=rig)
    qtbot.addWidget(panel)  # type: ignore[attr-defined]
    panel.camera_check.setChecked(False)
    panel.protocol_combo.setCurrentText("nlre")
    for k, v in SHORT_NLRE.items():
        panel.set_param(k, v)
    panel.out_edit.setText(str(out))
    panel.start_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle" and not panel.busy,  # type: ignore[attr-defined]
                    timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "completed", \
        panel.status_label.text()
    with RunReader(out) as r:
        return r.metadata


def service_run(rig: OpenRig, out: Path, tmp_path: Path) -> dict[str, str]:
    service = RunService(rig, "sim", Address(tmp_path / "service"))
    service.start(JobSpec("nlre", dict(SHORT_NLRE), str(out), camera=False, speed_text="max"))
    assert service._thread is not None
    service._thread.join(TIMEOUT_MS / 1000)
    assert not service.state.busy
    with RunReader(out) as r:
        assert r.status == "completed"
        return r.metadata


def test_the_three_ways_to_start_a_run_record_the_same_metadata(qtbot, rig, tmp_path,
                                                                 signal_handlers):
    from_cli = cli_run(tmp_path / "cli.h5")
    from_panel = panel_run(qtbot, rig, tmp_path / "panel.h5")
    from_service = service_run(rig, tmp_path / "service.h5", tmp_path)
    stated = rig.stated_parameters()
    assert stated and set(stated) == {"rig.m_kg", "rig.c0_N_s_per_m"}
    for name, md in (("rigctl run", from_cli), ("the window", from_panel),
                     ("the run service", from_service)):
        assert {k: md.get(k) for k in stated} == stated, f"{name}: {md}"
    common = [{k: v for k, v in md.items() if k not in PER_PATH}
              for md in (from_cli, from_panel, from_service)]
    assert common[0] == common[1] == common[2]
    assert from_panel["started_from"] == from_service["started_from"] == "gui"
