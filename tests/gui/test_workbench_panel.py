"""The Workbench tab (offscreen): compare, rank candidates, add the effect the ranking found, the
error falling in the history; a running fit cancelled (its worker processes gone); bad data said in
the log. Fits run in worker processes: the tests wait on the event loop, as the window does."""

from __future__ import annotations

import time

import numpy as np
import psutil
import pytest

from rigctl.gui.workbench_panel import WorkbenchPanel
from rigctl.model import build_model
from rigctl.workbench.campaigns import simulate_campaign, write_campaign

FIT_TIMEOUT_MS = 120_000


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """One TLRE run simulated with interface damping hidden (the paper's base model lacks it)."""
    folder = tmp_path_factory.mktemp("damped")
    model = build_model("paper", effects=["interface_damping"], params={"mu_s": 0.16})
    write_campaign(simulate_campaign(model, "tlre", seed=21, duration_scale=0.6), folder)
    return folder


@pytest.fixture
def panel(qtbot):
    p = WorkbenchPanel(workers=2)
    qtbot.addWidget(p)
    p.resize(1280, 820)
    yield p
    p.shutdown()


def wait_idle(qtbot, panel: WorkbenchPanel) -> None:
    qtbot.waitUntil(lambda: not panel.job.running, timeout=FIT_TIMEOUT_MS)


@pytest.mark.slow
def test_adding_the_effect_the_ranking_finds_makes_the_error_fall(panel, qtbot, campaign):
    panel.set_data([str(campaign)])
    assert panel.compare_button.isEnabled()
    panel.compare_button.click()
    assert panel.job.running and not panel.compare_button.isEnabled()  # the window goes on
    wait_idle(qtbot, panel)
    assert [m for m, _ in panel.history] == ["paper"], panel.log.toPlainText()
    base_error = panel.history[0][1]
    v = panel.view
    assert v is not None and v.n_events > 3
    o = v.overlays[0]
    assert len(o.t_s) > 100 and len(o.t_model_s) > 100
    assert float(np.max(panel.meas_curve.getData()[1])) == pytest.approx(float(np.max(o.ft_N)))
    assert panel.residual_table.rowCount() == len(v.features)
    assert np.any(v.residual != 0)  # the missing damping leaves structure in the residuals

    panel.rank(("interface_damping", "wear", "probe_drift"))
    wait_idle(qtbot, panel)
    assert panel.diagnosis is not None and panel.diagnosis.verdict == "interface_damping"
    assert panel.ranking_table.item(0, 0).text() == "interface_damping"
    assert panel.effect_combo.currentText() == "interface_damping"  # offered for adding

    panel.add_effect_button.click()
    wait_idle(qtbot, panel)
    assert [m for m, _ in panel.history] == ["paper", "paper + interface_damping"]
    assert panel.history[1][1] < 0.5 * base_error
    assert panel.request.effects == ("interface_damping",)
    assert panel.effect_combo.findText("interface_damping") < 0  # the model has it now
    x, y = panel.history_curve.getData()
    assert len(x) == 2 and y[1] < y[0]
    assert "-" in panel.log.toPlainText().splitlines()[-1]  # "(-97 % from ...)"


@pytest.mark.slow
def test_a_running_fit_is_cancelled_and_its_processes_end(panel, qtbot, campaign):
    panel.set_data([str(campaign)])
    panel.rank()  # every library effect: long enough to be caught running
    qtbot.waitUntil(lambda: "candidate effects" in panel.log.toPlainText(),
                    timeout=FIT_TIMEOUT_MS)
    pid = panel.job.pid
    assert pid is not None
    worker = psutil.Process(pid)
    qtbot.waitUntil(lambda: len(worker.children(recursive=True)) > 0, timeout=FIT_TIMEOUT_MS)
    family = [worker, *worker.children(recursive=True)]  # the candidate fits' processes too
    assert panel.cancel_button.isEnabled()
    panel.cancel_button.click()
    assert not panel.job.running and panel.compare_button.isEnabled()
    assert "cancelled" in panel.log.toPlainText()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p) for p in family):
        time.sleep(0.1)
    assert not any(_alive(p) for p in family)
    qtbot.wait(300)  # no late result arrives
    assert panel.diagnosis is None and panel.history == []


def _alive(p: psutil.Process) -> bool:
    try:
        return p.is_running() and p.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


@pytest.mark.slow
def test_bad_data_is_an_error_in_the_log_and_the_status_bar(panel, qtbot, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,ft_N\n0,1\n")
    messages: list[str] = []
    panel.status_message.connect(messages.append)
    panel.set_data([str(bad)])
    panel.compare()
    wait_idle(qtbot, panel)
    assert "ERROR" in panel.log.toPlainText() and "bad.csv" in panel.log.toPlainText()
    assert messages[-1].startswith("error:"), messages
    assert panel.history == [] and panel.compare_button.isEnabled()


def test_a_plugin_file_adds_its_effects_to_the_choice(panel, tmp_path):
    from tests.workbench.hidden import PLUGIN

    f = tmp_path / "drift.py"
    f.write_text(PLUGIN)
    assert panel.load_plugin(f) == ["force_sensor_drift"]
    assert panel.effect_combo.currentText() == "force_sensor_drift"
    assert panel.load_plugin(tmp_path / "missing.py") == []
    assert "missing.py" in panel.log.toPlainText()
