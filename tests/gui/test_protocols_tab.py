"""The Protocols tab (offscreen): progress held while paused, the refusing parameter marked, the
summary following the values, stale labels cleared, the run file shown once it exists, operator and
notes in the file; the queue of runs in the run service (real processes, simulated rig at speed max).
"""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from PySide6.QtWidgets import QTableWidget, QTableWidgetItem

from rigctl.config.loader import default_config
from rigctl.errors import InputError
from rigctl.gui.run_panel import RunPanel
from rigctl.runservice.client import spawn_service
from rigctl.runservice.queue import RunQueue
from rigctl.runservice.server import service_alive
from rigctl.runservice.wire import Address, JobSpec
from rigctl.storage.reader import RunReader

TIMEOUT_MS = 90_000
SHORT_TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1"}
SHORT_SWEEP = {"forces_N": "100, 150", "travel_m": "40e-6", "velocity_m_s": "1e-5",
               "preload_hold_s": "1", "settle_s": "1"}
SHORT_SHS = {"slide_m": "20e-6", "velocity_m_s": "1e-5", "holds_s": "1, 2",
             "preload_hold_s": "1", "settle_s": "1"}
LONG_SLIDE_TLRE = {**SHORT_TLRE, "travel_m": "400e-6", "velocity_m_s": "5e-6"}


@pytest.fixture
def panels():
    """Panels to shut down after the test (a run aborted to its safe state). A test using ``rig``
    requests it before ``panels``, so that the run ends before the rig is closed."""
    made: list[RunPanel] = []
    yield made
    for p in made:  # never leave a worker (or a loaded rig) behind
        if p.has_service:
            p.send_service("queue_abort", "test ended")
        assert p.shutdown(timeout_s=60.0)
        p.disconnect_service()


def make_panel(qtbot, panels: list[RunPanel], protocol: str = "tlre", **kw) -> RunPanel:
    panel = RunPanel(default_config(), "sim", **kw)
    # qtbot closes its widgets before the fixtures end: a failing test that leaves a run going must
    # not wait on the close dialog (say yes: the run is aborted to its safe state, then shut down)
    panel._ask = lambda question: True  # type: ignore[method-assign]
    qtbot.addWidget(panel)
    panels.append(panel)
    panel.camera_check.setChecked(False)
    panel.protocol_combo.setCurrentText(protocol)
    return panel


def cell(table: QTableWidget, row: int, col: int) -> QTableWidgetItem:
    item = table.item(row, col)
    assert item is not None, (row, col)
    return item


def set_params(panel: RunPanel, values: dict[str, str]) -> None:
    for k, v in values.items():
        panel.set_param(k, v)


def eta_numbers(panel: RunPanel) -> tuple[str, str]:
    """The ETA in rig and wall seconds as the label shows them."""
    m = re.search(r"ETA (\d+) s(?: \((~\d+|<1) s wall\))?", panel.progress_label.text())
    assert m is not None, panel.progress_label.text()
    return m.group(1), m.group(2) or ""


# ---------------------------------------------------------------- the fixed behaviours (in process)
@pytest.mark.slow
def test_progress_and_eta_stand_still_while_paused(qtbot, rig, panels, tmp_path):
    panel = make_panel(qtbot, panels, rig=rig)
    panel.out_edit.setText(str(tmp_path / "paused.h5"))
    set_params(panel, LONG_SLIDE_TLRE)
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    panel.start_button.click()
    qtbot.waitUntil(lambda: stage.position_m() > x0 + 30e-6, timeout=TIMEOUT_MS)  # sliding
    qtbot.waitUntil(lambda: panel.progress_bar.value() > 0, timeout=TIMEOUT_MS)
    panel.pause_button.click()
    qtbot.wait(100)
    held_bar, held_eta = panel.progress_bar.value(), eta_numbers(panel)
    samples = panel.samples_received
    # the rig's clock and the recording go on: 5 s of rig time while paused
    qtbot.waitUntil(lambda: panel.samples_received > samples + 5 * 1024, timeout=TIMEOUT_MS)
    assert "paused" in panel.progress_label.text()
    assert panel.progress_bar.value() == held_bar
    assert eta_numbers(panel) == held_eta
    panel.resume_button.click()
    qtbot.waitUntil(lambda: panel.progress_bar.value() > held_bar, timeout=TIMEOUT_MS)
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "completed"
    assert panel.progress_bar.value() == panel.progress_bar.maximum()


def test_a_limit_refusal_marks_the_parameter_causing_it_and_clears_when_edited(qtbot, rig, panels):
    panel = make_panel(qtbot, panels, rig=rig)
    panel.set_param("velocity_m_s", "2e-6")  # edited too, but within the limits
    panel.set_param("fn_N", "5000")
    panel.dry_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert "exceeds the limit 800 N" in panel.status_label.text()
    assert panel.marked_params() == ["fn_N"]
    row = list(panel.param_values()).index("fn_N")
    value = cell(panel.param_table, row, 1)
    assert "causes the refusal" in value.toolTip() and "800 N" in value.toolTip()
    assert value.background().color().name() == "#ffcdd2"
    other = cell(panel.param_table, list(panel.param_values()).index("velocity_m_s"), 1)
    assert other.background().color().alpha() == 0
    # the refusal is stale once the value changes: marks, red plan and red status cleared
    panel.set_param("fn_N", "300.0")
    assert panel.marked_params() == []
    assert "normal force" in value.toolTip()
    assert panel.plan_view.toPlainText() == ""
    assert "refused" not in panel.status_label.text()
    assert "c62828" not in panel.status_label.styleSheet()
    panel.dry_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert "within the limits" in panel.status_label.text()


def test_a_bad_value_marks_its_row(qtbot, panels):
    panel = make_panel(qtbot, panels)
    panel.set_param("travel_m", "far")
    panel.start_button.click()
    assert "travel_m" in panel.status_label.text() and not panel.busy
    assert panel.marked_params() == ["travel_m"]


def test_the_summary_follows_the_edited_values(qtbot, panels):
    panel = make_panel(qtbot, panels)
    text = panel.summary_label.text()
    assert "load Fn to 300 N" in text and "(x3)" in text  # the defaults: 3 repetitions
    panel.set_param("fn_N", "450")
    panel.set_param("repetitions", "2")
    text = panel.summary_label.text()
    assert "load Fn to 450 N" in text and "300 N" not in text, text
    assert "(x2)" in text and "fn_N = 450" in text
    panel.set_param("velocity_m_s", "slow")
    assert "not a valid set of values" in panel.summary_label.text()
    panel.protocol_combo.setCurrentText("force_sweep")
    text = panel.summary_label.text()
    assert "load Fn to 150 N" in text and "load Fn to 350 N" in text


def test_a_refused_start_leaves_no_starting_label(qtbot, rig, panels, tmp_path):
    panel = make_panel(qtbot, panels, rig=rig)
    out = tmp_path / "refused.h5"
    panel.out_edit.setText(str(out))
    panel.set_param("fn_N", "5000")
    panel.start_button.click()
    assert "starting" in panel.progress_label.text()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert "refused" in panel.status_label.text()
    assert "starting" not in panel.progress_label.text()
    assert panel.file_label.text() == "" and not out.exists()


@pytest.mark.slow
def test_the_run_file_is_shown_once_it_exists_and_records_operator_and_notes(qtbot, rig, panels,
                                                                            tmp_path):
    panel = make_panel(qtbot, panels, rig=rig)
    out = tmp_path / "named.h5"
    panel.out_edit.setText(str(out))
    panel.operator_edit.setText("A. Operator")
    panel.notes_edit.setText("PMMA boss #3, fresh glass")
    set_params(panel, SHORT_TLRE)
    panel.start_button.click()
    assert "not yet created" in panel.file_label.text()
    qtbot.waitUntil(lambda: panel.file_label.text() == f"run file: {out}", timeout=TIMEOUT_MS)
    assert out.exists() and panel.state == "running"  # shown while it records
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "completed"
    with RunReader(out) as r:
        s = r.summary()
        assert (s.operator, s.notes) == ("A. Operator", "PMMA boss #3, fresh glass")


# ---------------------------------------------------------------- the queue (run service)
@pytest.fixture
def service() -> Iterator[Address]:
    address = Address(Path(f"/tmp/rigctl-queue-{os.getpid()}-{time.monotonic_ns()}"))
    proc = spawn_service(address, "sim", "max", extra=["--idle-exit-s", "1"])
    try:
        deadline = time.monotonic() + 90.0
        while not service_alive(address):
            assert time.monotonic() < deadline and proc.poll() is None, "service did not start"
            time.sleep(0.1)
        yield address
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(60)
        shutil.rmtree(address.directory, ignore_errors=True)


def queue_two(qtbot, panel: RunPanel, first: Path, second: Path) -> None:
    panel.protocol_combo.setCurrentText("force_sweep")
    set_params(panel, SHORT_SWEEP)
    panel.out_edit.setText(str(first))
    assert panel.add_to_queue()
    panel.protocol_combo.setCurrentText("slide_hold_slide")
    set_params(panel, SHORT_SHS)
    panel.out_edit.setText(str(second))
    assert panel.add_to_queue()
    qtbot.waitUntil(lambda: len(panel.queue_view.state.items) == 2, timeout=TIMEOUT_MS)
    table = panel.queue_view.table
    assert [cell(table, r, 1).text() for r in range(2)] == ["force_sweep", "slide_hold_slide"]
    assert "forces_N=100, 150" in cell(table, 0, 2).text()
    assert [cell(table, r, 4).text() for r in range(2)] == ["pending", "pending"]


def statuses(panel: RunPanel) -> list[str]:
    return [it.status for it in panel.queue_view.state.items]


@pytest.mark.slow
def test_a_queue_of_two_runs_completes_both_files(qtbot, service, panels, tmp_path):
    panel = make_panel(qtbot, panels, speed="max", service=service)
    first, second = tmp_path / "q1_sweep.h5", tmp_path / "q2_shs.h5"
    queue_two(qtbot, panel, first, second)
    # move the second up and back down: the order is the operator's
    panel.queue_view.table.selectRow(1)
    panel.queue_view.up_button.click()
    qtbot.waitUntil(lambda: [it.spec.protocol for it in panel.queue_view.state.items]
                    == ["slide_hold_slide", "force_sweep"], timeout=TIMEOUT_MS)
    panel.queue_view.table.selectRow(0)
    panel.queue_view.down_button.click()
    qtbot.waitUntil(lambda: [it.spec.protocol for it in panel.queue_view.state.items]
                    == ["force_sweep", "slide_hold_slide"], timeout=TIMEOUT_MS)
    panel.queue_view.start_button.click()
    qtbot.waitUntil(lambda: statuses(panel)[0] == "running", timeout=TIMEOUT_MS)
    assert not panel.start_button.isEnabled()  # no single run while the queue runs
    qtbot.waitUntil(lambda: statuses(panel) == ["completed", "completed"]
                    and not panel.queue_view.state.running, timeout=TIMEOUT_MS * 2)
    assert "queue completed: 2 run(s)" in panel.queue_view.message_label.text()
    for path, protocol in ((first, "force_sweep"), (second, "slide_hold_slide")):
        with RunReader(path) as r:
            assert (r.status, r.protocol) == ("completed", protocol)
    with RunReader(first) as r:
        assert r.parameters["forces_N"] == [100.0, 150.0]


@pytest.mark.slow
def test_aborting_the_queue_mid_first_run_aborts_it_and_drops_the_rest(qtbot, service, panels,
                                                                       tmp_path):
    panel = make_panel(qtbot, panels, speed="max", service=service)
    first, second = tmp_path / "q1_sweep.h5", tmp_path / "q2_shs.h5"
    queue_two(qtbot, panel, first, second)
    panel.queue_view.start_button.click()
    # into the first run's slide (step 3 of the sweep: load, settle, slide)
    qtbot.waitUntil(lambda: panel._progress is not None and panel._progress[0] >= 3,
                    timeout=TIMEOUT_MS)
    assert panel.file_label.text() == f"run file: {first}"
    panel.pause_button.click()  # pause holds the current run; the queue waits with it
    qtbot.wait(1500)
    assert statuses(panel) == ["running", "pending"] and not second.exists()
    panel.queue_view.abort_button.click()
    qtbot.waitUntil(lambda: statuses(panel) == ["aborted", "dropped"], timeout=TIMEOUT_MS)
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert "queue aborted" in panel.queue_view.message_label.text()
    qtbot.wait(1500)  # nothing starts after an abort
    assert not second.exists()
    with RunReader(first) as r:
        assert r.status == "aborted"


# ---------------------------------------------------------------- the queue's rules (no processes)
def spec(name: str) -> JobSpec:
    return JobSpec("tlre", {}, f"/data/{name}.h5")


def test_a_run_that_does_not_complete_stops_the_queue_and_says_so() -> None:
    q = RunQueue()
    a, b, c = (q.add(spec(n)) for n in "abc")
    first = q.start()
    assert first is not None and first.queue_item == a
    nxt = q.finished(a, "completed", "")
    assert nxt is not None and nxt.queue_item == b
    assert q.finished(b, "failed", "StageFault: tangential alarm") is None
    st = q.state()
    assert not st.running and [it.status for it in st.items] == ["completed", "failed", "pending"]
    assert "item 2 (tlre) ended failed: StageFault" in st.message and "1 run(s) not started" in st.message
    again = q.start()  # the rest can be started again
    assert again is not None and again.queue_item == c


def test_queue_edits_follow_the_rules() -> None:
    q = RunQueue()
    a, b = q.add(spec("a")), q.add(spec("b"))
    with pytest.raises(InputError, match=r"already records to /data/a\.h5"):
        q.add(spec("a"))
    with pytest.raises(InputError, match="no run file"):
        q.add(JobSpec("tlre", {}, None))
    q.move(b, -1)
    assert [it.item for it in q.state().items] == [b, a]
    started = q.start()
    assert started is not None and started.queue_item == b
    with pytest.raises(InputError, match="running"):
        q.remove(b)
    with pytest.raises(InputError, match="only pending items move"):
        q.move(b, +1)
    assert q.abort("operator") is True  # a queued run is going: the service aborts it
    assert [it.status for it in q.state().items] == ["running", "dropped"]
    assert q.finished(b, "aborted", "operator") is None
    q.clear()
    assert q.state().items == ()
