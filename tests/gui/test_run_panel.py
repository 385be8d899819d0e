"""The run panel (offscreen): parameters, dry-run refusal, a short run to the end, abort to safety."""

from __future__ import annotations

import h5py
import pytest

from experiments.protocols import PROTOCOLS
from rigctl.config.loader import default_config
from rigctl.gui.param_table import format_value
from rigctl.gui.run_panel import RunPanel

SHORT_TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1"}
TIMEOUT_MS = 60_000


def make_panel(qtbot, **kw) -> RunPanel:
    panel = RunPanel(default_config(), "sim", **kw)
    qtbot.addWidget(panel)
    panel.camera_check.setChecked(False)
    panel.protocol_combo.setCurrentText("tlre")
    return panel


@pytest.fixture
def panels():
    made: list[RunPanel] = []
    yield made
    for p in made:  # never leave a worker (or a loaded rig) behind
        assert p.shutdown(timeout_s=30.0)


def test_parameter_table_shows_the_tlre_defaults(qtbot, panels):
    panel = make_panel(qtbot)
    panels.append(panel)
    tlre = PROTOCOLS["tlre"]
    assert panel.param_values() == {d.name: format_value(d.default) for d in tlre.params}
    row = [d.name for d in tlre.params].index("fn_N")
    assert panel.param_table.item(row, 1).text() == "300.0"
    assert panel.param_table.item(row, 2).text() == "N"
    assert "normal force" in panel.param_table.item(row, 0).toolTip()
    # a bad value names the parameter and starts nothing
    panel.set_param("velocity_m_s", "fast")
    panel.start_button.click()
    assert "velocity_m_s" in panel.status_label.text() and not panel.busy


def test_dry_run_refuses_a_force_over_the_limit_and_moves_nothing(qtbot, panels, rig):
    panel = make_panel(qtbot, rig=rig)
    panels.append(panel)
    x0 = rig.devices.tangential_stage.position_m()
    z0 = rig.devices.normal_stage.position_m()
    panel.set_param("fn_N", "5000")
    panel.dry_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    status = panel.status_label.text()
    assert "refused" in status and "exceeds the limit 800 N" in status, status
    assert "c62828" in panel.status_label.styleSheet()  # red
    assert "exceeds the limit" in panel.plan_view.toPlainText()
    assert rig.devices.tangential_stage.position_m() == x0
    assert rig.devices.normal_stage.position_m() == z0
    assert panel.samples_received == 0


@pytest.mark.slow
def test_a_short_tlre_runs_to_completion_from_start(qtbot, panels, tmp_path):
    panel = make_panel(qtbot, speed="max")
    panels.append(panel)
    out = tmp_path / "gui_tlre.h5"
    panel.out_edit.setText(str(out))
    for k, v in SHORT_TLRE.items():
        panel.set_param(k, v)
    panel.start_button.click()
    assert panel.busy and panel.abort_button.isEnabled()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    outcome = panel.last_outcome
    assert outcome is not None and outcome.status == "completed", panel.status_label.text()
    assert panel.status_label.text().startswith("completed")
    assert panel.progress_bar.value() == panel.progress_bar.maximum()
    assert panel.samples_received > 1000
    x, y = panel.fn_curve.getData()
    assert x is not None and len(x) > 0 and y.max() > 250.0  # the 300 N load was seen live
    assert "steps, estimated" in panel.plan_view.toPlainText()
    with h5py.File(out, "r") as f:
        assert f["entry/status"][()].decode() == "completed"


@pytest.mark.slow
def test_abort_during_a_run_releases_the_normal_load(qtbot, panels, rig, tmp_path):
    panel = make_panel(qtbot, rig=rig)
    panels.append(panel)
    panel.out_edit.setText(str(tmp_path / "gui_abort.h5"))
    for k, v in SHORT_TLRE.items():
        panel.set_param(k, v)
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    panel.start_button.click()
    qtbot.waitUntil(lambda: stage.position_m() > x0 + 30e-6, timeout=TIMEOUT_MS)  # sliding
    assert rig.sim.rig.state.fn_N > 250.0
    panel.pause_button.click()
    assert panel.resume_button.isEnabled() and "paused" in panel.status_label.text()
    panel.abort_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "aborted"
    assert panel.status_label.text().startswith("aborted")
    assert "aborted by the operator" in panel.status_label.text()
    assert not stage.status().moving
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # normal load released


@pytest.mark.slow
def test_closing_during_a_run_asks_then_aborts_to_a_safe_state(qtbot, panels, rig, tmp_path,
                                                                 monkeypatch):
    panel = make_panel(qtbot, rig=rig)
    panels.append(panel)
    asked: list[str] = []
    monkeypatch.setattr(panel, "_ask", lambda q: asked.append(q) or True)
    panel.out_edit.setText(str(tmp_path / "gui_close.h5"))
    for k, v in SHORT_TLRE.items():
        panel.set_param(k, v)
    panel.show()
    panel.start_button.click()
    qtbot.waitUntil(lambda: rig.sim.rig.state.fn_N > 100.0, timeout=TIMEOUT_MS)
    panel.close()
    assert asked and panel.isVisible()  # still open until the rig is safe
    qtbot.waitUntil(lambda: not panel.isVisible(), timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "aborted"
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)
