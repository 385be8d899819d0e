"""The Live tab (offscreen): forces and camera during a short TLRE on the simulated rig at speed max,
the run's events and file, the e-stop from the Live tab, the camera frames through the run service,
and the pieces it is made of (frame reduction, P(x), Isum, warning forwarding, bounded memory)."""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt

from rigctl.config.loader import default_config
from rigctl.gui.live_contact import LiveProfile
from rigctl.gui.live_view import LiveView, file_info, format_bytes
from rigctl.gui.main_window import ESTOP_KEY, MainWindow
from rigctl.gui.service_backend import ServiceBackend
from rigctl.runservice.events import WarningForwarder, drop_events
from rigctl.runservice.frames import FrameReducer, LiveFrame, downsample, intensity_sum
from rigctl.runservice.wire import JobSpec
from rigctl.storage.reader import RunReader
from tests.gui.service_session import service_session

SHORT_TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1"}
TIMEOUT_MS = 60_000


def tlre_window(qtbot, rig, out: Path, camera: bool = True) -> MainWindow:
    window = MainWindow(default_config(), "sim", rig=rig)
    qtbot.addWidget(window)
    panel = window.panel
    panel.camera_check.setChecked(camera)
    panel.protocol_combo.setCurrentText("tlre")
    for k, v in SHORT_TLRE.items():
        panel.set_param(k, v)
    panel.out_edit.setText(str(out))
    window.tabs.setCurrentWidget(window.live_view)
    window.show()
    qtbot.waitExposed(window)
    return window


def events_text(view: LiveView) -> str:
    return view.events.toPlainText()


@pytest.mark.slow
def test_live_tab_shows_forces_camera_events_and_file_during_a_tlre(qtbot, rig, tmp_path):
    out = tmp_path / "live.h5"
    window = tlre_window(qtbot, rig, out)
    view, panel = window.live_view, window.panel
    assert window.tabs.tabText(window.tabs.currentIndex()) == "Live"
    panel.start_button.click()
    # during the run: forces plotted and camera images shown while it records, P(x) of the contact
    # (a density over the contact region: mean 1, the analysis' 100 bins of x)
    def profile_shown() -> bool:
        px, _ = view.profile_curve.getData()
        return px is not None and len(px) == 100
    qtbot.waitUntil(lambda: view.images_shown >= 2 and view.plot.samples > 5000 and profile_shown(),
                    timeout=TIMEOUT_MS)
    assert panel.busy
    px, py = view.profile_curve.getData()
    assert abs(float(np.mean(py)) - 1.0) < 1e-9 and px[0] > 0 and px[-1] < 1
    region = view.contact.region
    assert region is not None and 0 < region.col0 < region.col1 < view.image_item.image.shape[1]
    assert "contact in columns" in view.image_label.text
    qtbot.waitUntil(lambda: "size" in view.file_label.text(), timeout=5000)
    assert str(out) in view.file_label.text() and "free on its disk" in view.file_label.text()
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "completed"
    view.redraw()
    # the force curves and Ft-delta hold the run's data (decimated, within the 60 s window)
    x, y = view.plot.ft_curve.getData()
    assert x is not None and len(x) > 100 and np.nanmax(y) > 10.0  # Ft rose while sliding
    _, fn = view.plot.fn_curve.getData()
    assert np.nanmax(fn) > 250.0  # the 300 N pre-load
    assert view.plot.phase_curve is not None
    dx, dy = view.plot.phase_curve.getData()
    assert len(dx) > 100 and np.nanmax(dx) > 10e-6 and np.nanmax(dy) > 10.0  # delta grew, Ft rose
    # camera: an image and Isum values of every frame
    image = view.image_item.image
    assert image is not None and image.ndim == 2 and image.shape[1] <= 320
    it, isum = view.isum_curve.getData()
    assert len(it) >= view.frames_received >= 2 and np.all(np.asarray(isum) > 0)
    # events: start and outcome, each with its level; the file label: path, size, free space
    text = events_text(view)
    assert "starting tlre" in text and "completed" in text
    # the window's status bar says what the run panel says (it said "ready" through a run)
    assert window.statusBar().currentMessage() == panel.status_label.text()
    assert "completed" in window.statusBar().currentMessage()
    qtbot.waitUntil(lambda: f"size {format_bytes(out.stat().st_size)}" in view.file_label.text(),
                    timeout=5000)
    with RunReader(out) as r:
        assert r.status == "completed"


@pytest.mark.slow
def test_a_finished_run_s_last_frame_is_not_shown_in_the_next_run(qtbot, rig, tmp_path):
    """A run's frame forwarder flushes its last frame after the run ended; a run started at once
    must not show it: it put the previous run's rig times (27 s) into the new run's Isum plot,
    whose times start again at 0, and the plot kept a range of the old run's end."""
    window = tlre_window(qtbot, rig, tmp_path / "first.h5")
    view, panel = window.live_view, window.panel
    panel.set_param("travel_m", "60e-6")
    panel.start_button.click()
    qtbot.waitUntil(lambda: panel.state == "idle" and not panel.busy, timeout=TIMEOUT_MS)
    first_end_s = float(view.isum_history.view("t_s")[-1]) - view._t_origin
    panel.out_edit.setText(str(tmp_path / "second.h5"))
    panel.start_button.click()  # at once: the first run's forwarder may still be flushing
    assert panel.state == "running"
    qtbot.waitUntil(lambda: view.frames_received >= 5, timeout=TIMEOUT_MS)
    t = view.isum_history.view("t_s") - view._t_origin
    assert t[0] < 1.0 < first_end_s and np.all(np.diff(t) > 0)  # the second run's own frames
    qtbot.waitUntil(lambda: panel.state == "idle" and not panel.busy, timeout=TIMEOUT_MS)


@pytest.mark.slow
def test_a_frame_of_an_earlier_job_is_dropped(qtbot, rig):
    window = tlre_window(qtbot, rig, Path("unused.h5"), camera=True)
    panel = window.panel
    try:
        panel._begin("tlre", None, True, 1.0, None)  # a dry run begins
        old = panel._job_serial
        panel._begin("tlre", None, True, 1.0, None)  # and another
        frames = panel._runs._frames  # the in-process back-end's: its forwarders put there
        frames.put(old, "frame of the earlier job")
        frames.put(panel._job_serial, "frame of this job")
        kept = panel._runs.drain_frames()
    finally:
        panel._set_state("idle")  # nothing ran: the window closes without asking
    assert kept == ["frame of this job"]


class _NoService:
    """A run service's client that sends nowhere."""

    def send(self, kind: str, payload: object = None) -> bool:
        return True

    def close(self) -> None:
        pass


@pytest.mark.slow
def test_a_queued_run_keeps_its_first_frame_and_drops_the_previous_run_s(qtbot, rig):
    """The run service's messages in order: a frame of the previous run, the queued run's
    ``started``, its first frame. The window begins the queued run later, in the GUI thread; the
    reset must fall between the two frames, not when the GUI thread gets to it (then the queued
    run's first frame, with its first Isum values, went too)."""
    window = tlre_window(qtbot, rig, Path("unused.h5"), camera=True)
    panel = window.panel
    backend = ServiceBackend(panel.signals, lambda on_message: _NoService())
    panel._runs = backend  # the run service's back-end, its messages fed by the test
    spec = JobSpec("tlre", {}, None, dry=True, queue_item=7)
    try:
        messages = [("frame", "last frame of the previous run"), ("started", spec),
                    ("frame", "first frame of the queued run")]
        reader = threading.Thread(target=lambda: [backend.on_message(*m) for m in messages])
        reader.start()  # as the client's reader thread: `started` is queued into the GUI thread
        reader.join()
        qtbot.waitUntil(lambda: panel._queue_item == 7, timeout=5000)  # begun in the GUI thread
        assert panel.busy
        kept = backend.drain_frames()
    finally:
        backend.ended()
        panel._set_state("idle")  # nothing ran: the window closes without asking
    assert kept == ["first frame of the queued run"]


@pytest.mark.slow
def test_estop_from_the_live_tab_aborts_and_is_listed(qtbot, rig, tmp_path):
    out = tmp_path / "live_estop.h5"
    window = tlre_window(qtbot, rig, out, camera=False)
    view, panel = window.live_view, window.panel
    stage = rig.devices.tangential_stage
    x0 = stage.position_m()
    panel.start_button.click()
    qtbot.waitUntil(lambda: stage.position_m() > x0 + 30e-6, timeout=TIMEOUT_MS)  # sliding
    assert window.tabs.currentWidget() is view and window.estop_button.isVisible()
    view.events.setFocus()
    qtbot.keyClick(view.events, getattr(Qt.Key, f"Key_{ESTOP_KEY}"))
    assert stage.emergency_stop_registry.reason is not None
    qtbot.waitUntil(lambda: panel.state == "idle", timeout=TIMEOUT_MS)
    assert panel.last_outcome is not None and panel.last_outcome.status == "aborted"
    assert not stage.status().moving
    text = events_text(view)
    assert "EMERGENCY STOP" in text and "aborted" in text
    # the device poll sees the latched e-stop and lists it
    qtbot.waitUntil(lambda: "emergency stop latched" in events_text(view), timeout=5000)


@pytest.mark.slow
def test_history_stays_bounded_when_fed_an_hour(qtbot):
    view = LiveView(rate_hz=1024.0, window_s=10.0, camera_rate_hz=60.0)
    qtbot.addWidget(view)
    t0 = 0.0
    img = np.full((48, 64), 100, np.uint8)
    for _ in range(3600 // 10):  # 10 s of data per step
        t = t0 + np.arange(10240) / 1024.0
        view.feed_blocks([{"t_s": t, "ft_N": np.sin(t), "fn_N": np.full_like(t, 300.0),
                           "d1_m": t * 1e-6, "d2_m": np.zeros_like(t)}])
        ft = t0 + np.arange(600) / 60.0
        view.feed_frames([LiveFrame(float(ft[-1]), img, 1, ft, np.full(600, 1.0))])
        t0 += 10.0
    assert view.plot.samples == 3600 * 1024
    assert len(view.plot.history) <= 10 * 1024 + 1
    assert len(view.isum_history) <= 10 * 60 + 1
    assert view.redraw()
    x, _ = view.plot.ft_curve.getData()
    assert x[-1] - x[0] <= 10.0 + 1e-6 and len(x) <= view.plot.max_points
    view.shutdown()


# ---------------------------------------------------------------------- the pieces
def test_isum_is_the_sum_of_every_pixel():
    image = np.zeros((4, 5), np.uint8)
    image[:, 0] = 10
    image[1, 3] = 30
    assert intensity_sum(image) == 4 * 10 + 30  # Eq. 1
    assert intensity_sum(np.full((480, 640), 255, np.uint8)) == 480 * 640 * 255  # no uint8 overflow


def test_live_profile_is_the_analysis_p_over_the_contact_region():
    rng = np.random.default_rng(1)
    live = LiveProfile(n_bins=10)

    def frame(contact: bool) -> np.ndarray:
        """A camera frame as the simulated camera makes one: dark level 6, read noise, rounded."""
        img: np.ndarray = 6.0 + rng.normal(0, 1.2, (60, 100))
        if contact:
            img[:, 30:70] += np.linspace(10, 100, 40)[None, :]  # brighter towards the front end
        return np.rint(np.clip(img, 0, 255)).astype(np.uint8)

    for _ in range(3):  # a dark field: no contact, no P
        assert live.add(frame(False)) is None
    assert live.region is None and "no contact" in live.problem
    live.clear()
    for _ in range(8):
        p = live.add(frame(True))
    assert live.region is not None and abs(live.region.col0 - 30) <= 1 and abs(live.region.col1 - 70) <= 1
    assert p is not None and p.shape == (10,) and abs(float(p.mean()) - 1.0) < 1e-9
    assert np.all(np.diff(p) > 0)  # rises from the back end to the front end
    np.testing.assert_allclose(live.x_centres, (np.arange(10) + 0.5) / 10)


def test_downsample_averages_full_blocks():
    image = np.arange(480 * 640, dtype=np.uint32).reshape(480, 640) % 256
    small, factor = downsample(image.astype(np.uint8), 320)
    assert factor == 2 and small.shape == (240, 320) and small.dtype == np.uint8
    assert small[0, 0] == round(np.mean(image[:2, :2]))
    same, f1 = downsample(np.zeros((10, 100), np.uint8), 320)
    assert f1 == 1 and same.shape == (10, 100)
    odd, f3 = downsample(np.ones((7, 700), np.uint8) * 9, 320)
    assert f3 == 3 and odd.shape == (2, 233) and np.all(odd == 9)


def test_reducer_sends_a_few_images_but_every_isum():
    clock = [0.0]
    reducer = FrameReducer(rate_hz=4.0, max_width_px=32, clock=lambda: clock[0])
    sent = []
    for i in range(60):  # one second of 60 Hz frames
        clock[0] = i / 60.0
        img = np.full((40, 64), i, np.uint8)
        out = reducer.add(i / 60.0, img)
        if out is not None:
            sent.append(out)
    last = reducer.flush()
    assert last is not None
    sent.append(last)
    assert 4 <= len(sent) <= 6
    isums = np.concatenate([s.isum for s in sent])
    np.testing.assert_allclose(isums, [40 * 64 * i for i in range(60)])
    assert np.all(np.diff(np.concatenate([s.isum_t_s for s in sent])) > 0)
    assert all(s.image.shape == (20, 32) and s.factor == 2 for s in sent)
    assert reducer.flush() is None


def test_warnings_and_drops_become_events():
    got: list[tuple[str, str]] = []
    fwd = WarningForwarder(lambda level, text: got.append((level, text))).install()
    try:
        logging.getLogger("rigctl.acquisition.session").warning("d1_m: probe over range at %d", 3)
        logging.getLogger("rigctl.acquisition.session").info("not an event")
        logging.getLogger("somebody.else").warning("not ours")
        logging.getLogger("rigctl.runservice").warning("sent by the service itself")
    finally:
        fwd.remove()
    logging.getLogger("rigctl.acquisition.session").warning("after removal")
    assert got == [("warning", "d1_m: probe over range at 3")]

    @dataclass
    class Stats:
        daq_dropped: int = 0
        frames_dropped: int = 0

    seen: dict[str, int] = {}
    assert list(drop_events(Stats(), seen)) == []
    events = list(drop_events(Stats(daq_dropped=12), seen))
    assert len(events) == 1 and "12 samples lost by the DAQ" in events[0][1]
    assert list(drop_events(Stats(daq_dropped=12), seen)) == []  # only growth is news


def test_file_info_of_a_missing_file_says_so(tmp_path):
    info = file_info(tmp_path / "not_yet.h5")
    assert info.size_bytes is None and info.free_bytes and "not there yet" in info.problem
    (tmp_path / "a.h5").write_bytes(b"x" * 2500)
    info = file_info(tmp_path / "a.h5")
    assert info.size_bytes == 2500 and format_bytes(2500) == "2.5 kB"


@pytest.mark.slow
def test_run_service_forwards_camera_images_and_pause_resume_events(tmp_path):
    with service_session("live") as session:
        client, inbox, proc = session.client, session.inbox, session.proc
        out = tmp_path / "service_live.h5"
        client.send("start", JobSpec("tlre", SHORT_TLRE, str(out), camera=True, speed_text="10"))
        frames: list[LiveFrame] = []
        logs: list[str] = []
        paused = resumed = False
        deadline = time.monotonic() + 120
        while True:
            kind, payload = inbox.get(timeout=max(0.1, deadline - time.monotonic()))
            if kind == "frame":
                frames.append(payload)
                if len(frames) == 3 and not paused:
                    client.send("pause")
                    paused = True
                elif paused and not resumed:
                    client.send("resume")
                    resumed = True
            elif kind == "log":
                logs.append(payload[1])
            elif kind == "done":
                break
        assert payload.kind == "run" and payload.outcome.status == "completed"
        assert len(frames) >= 3
        for f in frames:
            assert isinstance(f, LiveFrame) and f.image.dtype == np.uint8
            assert f.image.shape[1] <= 320 and f.factor >= 2  # 640 px wide camera, downsampled
        isum_t = np.concatenate([f.isum_t_s for f in frames])
        assert np.all(np.diff(isum_t) > 0)
        # Isum of every camera frame, far more values than images sent
        assert isum_t.size > 3 * len(frames)
        assert any("paused" in line for line in logs) and any("resumed" in line for line in logs)
        client.send("shutdown")
        client.close()
        proc.wait(60)


@pytest.mark.slow
def test_run_service_sends_a_run_s_live_data_before_its_done(tmp_path):
    """Every camera frame and DAQ block of a run reaches a client before the run's ``done``: the
    forwarders flush their last items after the run ends, and a queued run starts right after
    ``done``; a window resets its live view there, so a later item of the old run would be shown
    in the new one (its rig times in the new run's plots, which start again at 0)."""
    with service_session("order") as session:
        client, inbox, proc = session.client, session.inbox, session.proc
        out = tmp_path / "service_order.h5"
        client.send("start", JobSpec("tlre", {**SHORT_TLRE, "travel_m": "60e-6"}, str(out),
                                     camera=True, speed_text="10"))
        kinds: list[str] = []
        deadline = time.monotonic() + 120
        while "done" not in kinds:
            kind, payload = inbox.get(timeout=max(0.1, deadline - time.monotonic()))
            kinds.append(kind)
        assert payload.kind == "run" and payload.outcome.status == "completed"
        assert "frame" in kinds and "daq" in kinds
        time.sleep(1.0)  # what the forwarders would still flush
        late = []
        while not inbox.empty():
            late.append(inbox.get_nowait()[0])
        assert not {"frame", "daq"} & set(late), late
        client.send("shutdown")
        client.close()
        proc.wait(60)
