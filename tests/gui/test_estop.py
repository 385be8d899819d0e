"""Emergency stop: always visible and enabled, on the application-wide key F12, from any state.

In process (a simulated rig handed to the window) and in the run service (real processes): mid-run
the drivers' latched emergency stop stops both stages, motion is refused until reset, the run ends
``aborted`` naming the e-stop.
"""

from __future__ import annotations

import time

import pytest
from PySide6.QtCore import Qt

from drivers.errors import EmergencyStopActive
from rigctl.config.loader import default_config
from rigctl.gui.main_window import ESTOP_KEY, MainWindow
from rigctl.runservice.wire import JobSpec
from rigctl.storage.reader import RunReader
from tests.gui.service_session import service_session

SHORT_TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1"}
TIMEOUT_MS = 60_000


@pytest.mark.slow
def test_f12_mid_run_from_another_widget_stops_the_stages_and_aborts(qtbot, rig, tmp_path):
    window = MainWindow(default_config(), "sim", rig=rig)
    qtbot.addWidget(window)
    panel = window.panel
    panel.camera_check.setChecked(False)
    panel.protocol_combo.setCurrentText("tlre")
    for k, v in SHORT_TLRE.items():
        panel.set_param(k, v)
    out = tmp_path / "estop.h5"
    panel.out_edit.setText(str(out))
    window.show()
    qtbot.waitExposed(window)
    window.activateWindow()
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    panel.start_button.click()
    qtbot.waitUntil(lambda: stage.position_m() > x0 + 30e-6, timeout=TIMEOUT_MS)  # sliding
    assert window.estop_button.isVisible() and window.estop_button.isEnabled()
    panel.plan_view.setFocus()  # the key works wherever the focus is
    qtbot.keyClick(panel.plan_view, getattr(Qt.Key, f"Key_{ESTOP_KEY}"))
    reg = stage.emergency_stop_registry
    assert reg.reason is not None and "emergency stop" in reg.reason
    assert "EMERGENCY STOP" in window.statusBar().currentMessage()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "aborted"
    assert "emergency stop" in (panel.last_outcome.error or "")
    assert not stage.status().moving
    with pytest.raises(EmergencyStopActive):  # latched: motion refused until reset
        stage.move_relative(1e-6, 1e-5)
    assert window.estop_button.isEnabled()  # still enabled after it fired
    with RunReader(out) as r:
        assert r.status == "aborted"


def test_estop_when_idle_says_nothing_is_open(qtbot):
    window = MainWindow(default_config(), "sim")
    qtbot.addWidget(window)
    window.emergency_stop()
    assert "no rig is open" in window.statusBar().currentMessage()


@pytest.mark.slow
def test_estop_through_the_run_service_aborts_the_run(tmp_path):
    with service_session("estop") as session:
        client, inbox, proc = session.client, session.inbox, session.proc
        out = tmp_path / "estop_service.h5"
        client.send("start", JobSpec("tlre", SHORT_TLRE, str(out), camera=False, speed_text="10"))
        deadline = time.monotonic() + 90
        while True:
            kind, payload = inbox.get(timeout=max(0.1, deadline - time.monotonic()))
            if kind == "progress" and "slide" in payload[2]:
                break
        time.sleep(0.5)
        client.send("estop", "emergency stop by the operator")
        while True:
            kind, payload = inbox.get(timeout=60)
            if kind == "done":
                break
        assert payload.kind == "run" and payload.outcome.status == "aborted"
        assert "emergency stop" in payload.outcome.error

        def next_of(kind: str, pred=lambda p: True):
            end = time.monotonic() + 30
            while time.monotonic() < end:
                k, p = inbox.get(timeout=30)
                if k == kind and pred(p):
                    return p
            raise AssertionError(f"no {kind} message")

        snap = next_of("devices")  # the Devices tab's view through the service
        assert snap.estop and "emergency stop" in snap.estop and not snap.busy
        client.send("jog", ("tangential", 5e-6, 1e-5))
        ok, text = next_of("jog_result")
        assert not ok and "emergency" in text.lower()
        client.send("reset_estop")
        next_of("devices", lambda p: p.estop is None)
        client.send("jog", ("tangential", 5e-6, 1e-5))
        ok, text = next_of("jog_result")
        assert ok, text
        client.send("shutdown")
        client.close()
        proc.wait(60)
        with RunReader(out) as r:
            assert r.status == "aborted"
            assert any(e.name == "safe_state" for e in r.events())
