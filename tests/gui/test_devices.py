"""Devices tab: positions, limits shown, a jog beyond a limit refused (saying why), a jog within moves."""

from __future__ import annotations

import pytest

from rigctl.config.loader import default_config
from rigctl.gui.main_window import MainWindow
from rigctl.rigs import open_rig

TIMEOUT_MS = 30_000


@pytest.fixture
def rig():
    with open_rig("sim", default_config(), speed=1.0) as r:  # a clock that runs between runs
        yield r
        for stage in (r.devices.tangential_stage, r.devices.normal_stage):
            stage.emergency_stop_registry.reset()


@pytest.fixture
def window(qtbot, rig):
    w = MainWindow(default_config(), "sim", rig=rig)
    qtbot.addWidget(w)
    w.tabs.setCurrentWidget(w.devices)
    qtbot.waitUntil(lambda: w.devices.last_snapshot is not None, timeout=TIMEOUT_MS)
    return w


def test_limits_and_positions_are_shown(window, rig):
    box = window.devices.axes["tangential"]
    lim = rig.devices.tangential_stage.limits
    assert f"{lim.max_position_m * 1e3:g} mm" in box.limits.text()
    assert f"{lim.max_velocity_m_s * 1e6:g} um/s" in box.limits.text()
    assert box.position.text().endswith(" um")
    assert "not triggered" in window.devices.estop_label.text()


def test_a_jog_beyond_the_stroke_is_refused_and_says_why(qtbot, window, rig):
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    box = window.devices.axes["tangential"]
    box.step_um.setValue((stage.limits.max_position_m - x0) * 1e6 + 1000.0)  # 1 mm past the end
    box.plus.click()
    text = window.devices.jog_label.text()
    assert text.startswith("jog refused") and "maximum" in text, text
    assert "c62828" in window.devices.jog_label.styleSheet()
    assert stage.position_m() == x0 and not stage.status().moving


def test_a_jog_too_fast_is_refused_naming_the_speed_limit(window, rig):
    stage = rig.devices.normal_stage
    box = window.devices.axes["normal"]
    box.speed_um_s.setValue(stage.limits.max_velocity_m_s * 1e6 * 2)
    box.plus.click()
    assert "refused" in window.devices.jog_label.text() and "velocity" in window.devices.jog_label.text()


@pytest.mark.slow
def test_a_jog_within_the_limits_moves_the_stage(qtbot, window, rig):
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    box = window.devices.axes["tangential"]
    box.step_um.setValue(5.0)
    box.speed_um_s.setValue(50.0)
    box.plus.click()
    assert "moving" in window.devices.jog_label.text()
    qtbot.waitUntil(lambda: abs(stage.position_m() - (x0 + 5e-6)) < 0.2e-6 and not stage.status().moving,
                    timeout=TIMEOUT_MS)


@pytest.mark.slow
def test_after_an_estop_jogs_are_refused_until_reset(qtbot, window, rig):
    window.emergency_stop()
    qtbot.waitUntil(lambda: "E-STOP ACTIVE" in window.devices.estop_label.text(), timeout=TIMEOUT_MS)
    assert window.devices.reset_button.isEnabled()
    window.devices.axes["tangential"].plus.click()
    assert "refused" in window.devices.jog_label.text() and "emergency" in window.devices.jog_label.text()
    window.devices.reset_button.click()
    qtbot.waitUntil(lambda: "not triggered" in window.devices.estop_label.text(), timeout=TIMEOUT_MS)
    box = window.devices.axes["tangential"]
    box.step_um.setValue(2.0)
    box.speed_um_s.setValue(50.0)
    box.plus.click()  # the stage's e-stop alarm was cleared with the reset
    assert "moving" in window.devices.jog_label.text(), window.devices.jog_label.text()


@pytest.mark.slow
def test_readings_during_a_run_come_from_the_live_data(window, monkeypatch):
    """With the rig held by the window (no run service), the readings line shows the latest Ft, Fn
    and delta of the live data while a run is going, and nothing between runs."""
    import numpy as np

    from rigctl.gui.run_panel import RunPanel

    t = np.arange(10) / 1024.0
    block = {"t_s": t, "ft_N": np.full(10, 12.5), "fn_N": np.full(10, 300.25),
             "d1_m": np.full(10, 40e-6), "d2_m": np.full(10, 10e-6)}
    window.panel.live.feed([block])
    window._local_snapshot()
    assert "Ft" not in window.devices.readings.text()  # no run: nothing is read
    monkeypatch.setattr(RunPanel, "busy", property(lambda self: True))
    window._local_snapshot()
    text = window.devices.readings.text()
    assert "Ft 12.50 N" in text and "Fn 300.25 N" in text and "delta 30.00 um" in text, text
