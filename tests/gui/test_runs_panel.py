"""The Runs tab (offscreen): a finished run's plots, events, status and parameters; a run followed
while it is recorded by another process; CSV export; "run again" filling the Protocols tab; the
analysis report in a worker process."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rigctl.config.loader import default_config
from rigctl.gui.main_window import MainWindow
from rigctl.gui.param_table import format_value
from rigctl.gui.runs_panel import OVERVIEW_POINTS, RunsPanel
from rigctl.io.csv_format import read_csv
from rigctl.storage import RunReader
from tests.gui.growing_run_writer import PARAMETERS, write_run

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_MS = 60_000


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("runs") / "finished.h5"
    write_run(str(path), 40.0, period_s=0.0)
    return path


@pytest.fixture
def panel(qtbot):
    p = RunsPanel()
    qtbot.addWidget(p)
    p.resize(1200, 760)
    yield p
    p.shutdown()


@pytest.mark.slow
def test_a_finished_run_shows_its_whole_record_events_status_and_parameters(panel, qtbot,
                                                                         finished_run):
    messages: list[str] = []
    panel.status_message.connect(messages.append)
    assert panel.open(finished_run)
    qtbot.waitUntil(lambda: panel._reader is None, timeout=TIMEOUT_MS)  # all read, file released
    with RunReader(finished_run) as r:
        d = r.read_daq()
        n = r.n_samples
        events = r.events()
    assert panel.samples_read == n and panel.status == "completed"
    assert "completed" in panel.status_label.text()
    # the overview is decimated but keeps the extremes of Ft exactly
    t, ft = (np.asarray(a) for a in panel.ft_curve.getData())
    assert 100 < len(ft) <= OVERVIEW_POINTS + 2 * panel._envelope.bin_size < n
    assert ft.max() == d["ft_N"].max() and ft.min() == d["ft_N"].min()
    bin_s = panel._envelope.bin_size / 1024.0  # the first and last points are in the end bins
    assert d["t_s"][0] <= t[0] < d["t_s"][0] + bin_s and d["t_s"][-1] - bin_s < t[-1] <= d["t_s"][-1]
    # Ft against delta: real sample pairs
    x, y = (np.asarray(a) for a in panel.loop_curve.getData())
    delta = d["d1_m"] - d["d2_m"]
    k = int(np.argmax(y))
    assert x[k] == delta[int(np.argmax(d["ft_N"]))]
    assert panel.events_table.rowCount() == len(events) == 2
    assert panel.events_table.item(1, 1).text() == "end"
    params = {panel.params_table.item(i, 0).text(): panel.params_table.item(i, 1).text()
              for i in range(panel.params_table.rowCount())}
    assert params["fn_N"] == "250.0" and params["repetitions"] == "1"
    assert "test rig" in panel.config_view.toPlainText()
    assert any("opened" in m for m in messages)


@pytest.mark.slow
def test_a_run_being_recorded_is_followed_as_it_grows(panel, qtbot, tmp_path):
    out = tmp_path / "growing.h5"
    proc = subprocess.Popen([sys.executable, "-m", "tests.gui.growing_run_writer", str(out), "12"],
                            cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        assert panel.open(out)
        assert panel.status == "running" and "being recorded" in panel.status_label.text()
        first = panel.samples_read
        assert first > 0
        qtbot.waitUntil(lambda: panel.samples_read > first + 1024, timeout=TIMEOUT_MS)
        assert panel.status == "running"
        t_shown = float(panel.ft_curve.getData()[0][-1])
        qtbot.waitUntil(lambda: panel.status == "completed", timeout=TIMEOUT_MS)
        assert proc.wait(timeout=30) == 0
    finally:
        proc.kill()
        proc.wait()
    qtbot.waitUntil(lambda: panel._reader is None, timeout=TIMEOUT_MS)
    with RunReader(out) as r:
        assert panel.samples_read == r.n_samples
    t = panel.ft_curve.getData()[0]
    assert t[-1] > t_shown + 2.0 and t[-1] > 11.9  # the plots grew to the end of the run
    assert panel.events_table.rowCount() == 2
    assert "completed" in panel.status_label.text()


@pytest.mark.slow
def test_export_writes_the_runs_samples_refuses_to_overwrite_and_the_csv_opens(panel, qtbot, finished_run,
                                                               tmp_path):
    assert panel.open(finished_run)
    qtbot.waitUntil(lambda: panel._reader is None, timeout=TIMEOUT_MS)
    csv = tmp_path / "finished.csv"
    assert panel.export_csv(csv)
    run = read_csv(csv)
    with RunReader(finished_run) as r:
        d = r.read_daq()
    assert run.n_samples == len(d["t_s"])
    np.testing.assert_allclose(run.ft_N, d["ft_N"], rtol=1e-9)
    assert run.metadata["run.status"] == "completed" and run.metadata["run.protocol"] == "tlre"
    size = csv.stat().st_size
    assert not panel.export_csv(csv)  # exists: refused, said, the file left alone
    assert "already exists" in panel.log.toPlainText()
    assert csv.stat().st_size == size
    # the CSV opens in the tab too (the loader of rigctl analyse), its provenance shown
    assert panel.open(csv)
    assert panel.kind == "csv" and panel.status == "completed"
    assert float(np.max(panel.ft_curve.getData()[1])) == float(np.max(d["ft_N"]))
    shown = {panel.info_table.item(i, 0).text(): panel.info_table.item(i, 1).text()
             for i in range(panel.info_table.rowCount())}
    assert shown["protocol"] == "tlre" and shown["# run.status"] == "completed"
    assert not panel.export_button.isEnabled() and not panel.again_button.isEnabled()


def test_run_again_fills_the_protocols_tab_with_the_runs_protocol_and_parameters(qtbot,
                                                                               finished_run):
    window = MainWindow(default_config(), "sim")
    qtbot.addWidget(window)
    try:
        protocols = window.panel
        protocols.protocol_combo.setCurrentText("slide_hold_slide")
        assert window.runs.open(finished_run)
        qtbot.waitUntil(lambda: window.runs._reader is None, timeout=TIMEOUT_MS)
        assert window.runs.again_button.isEnabled()
        window.runs.again_button.click()
        assert window.tabs.currentWidget() is protocols
        assert protocols.protocol.name == "tlre"
        values = protocols.param_values()
        for name, value in PARAMETERS.items():
            assert values[name] == format_value(value), name
        assert "tlre" in window.statusBar().currentMessage()
    finally:
        window.runs.shutdown()
        window.workbench.shutdown()


@pytest.mark.slow
def test_the_analysis_report_is_made_in_a_worker_process(panel, qtbot, finished_run, tmp_path):
    assert panel.open(finished_run)
    qtbot.waitUntil(lambda: panel._reader is None, timeout=TIMEOUT_MS)
    out = tmp_path / "report"
    assert panel.analyse(out)
    assert panel.job.running and panel.cancel_button.isEnabled()
    assert not panel.analyse_button.isEnabled()
    qtbot.waitUntil(lambda: not panel.job.running, timeout=120_000)
    assert panel.report is not None, panel.log.toPlainText()
    assert Path(panel.report.index) == out / "index.html" and (out / "index.html").is_file()
    assert panel.report.figures and all(Path(f).is_file() for f in panel.report.figures)
    assert str(out / "index.html") in panel.report_view.toPlainText()
    assert panel.open_report_button.isEnabled()


def test_a_file_that_is_not_a_run_is_an_error_in_the_log_not_a_crash(panel, tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5 at all")
    messages: list[str] = []
    panel.status_message.connect(messages.append)
    assert not panel.open(bad)
    assert "bad.h5" in panel.log.toPlainText() and "ERROR" in panel.log.toPlainText()
    assert messages and messages[-1].startswith("error:")
    assert panel.kind == "" and not panel.export_button.isEnabled()
