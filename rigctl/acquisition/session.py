"""One acquisition session: DAQ, camera and stage positions recorded concurrently into a run file.

Threads (docs/acquisition.md):

* **daq** reads blocks from the DAQ (sample times from its counter), maps Fx/Fy/Fz and the analog
  channels to ft_N, fn_N, d1_m, d2_m with the configured ChannelMap, polls both stage positions once
  per block, places each poll at the device time it was made (:meth:`Acquisition.device_now_s`)
  and interpolates the polls linearly onto the block's samples, feeds the normal-force guard,
  updates the host-to-device clock map and the recent history, publishes the block to subscribers,
  and queues it for the writer.
* **camera** reads frames, places each on the device time axis through the clock map and queues it.
* **writer** owns the :class:`~rigctl.storage.RunWriter` (single-threaded by contract): it drains the
  bounded queue in arrival order (data, frames, step markers), flushes at the writer's interval, and
  at the end closes the file with the run's status.

Nothing is lost silently: device drops (counter gaps), camera drops (sequence gaps), items refused by a
full writer queue and subscribers' own losses are all counted in :class:`AcquisitionStats` and the
first two are in the run file. A device error in any thread is kept and re-raised by :meth:`check`
(the procedure runner polls it at least every 0.1 s and brings the rig to a safe state).
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drivers.errors import DeviceTimeout
from drivers.interfaces import Camera, Daq, DaqBlock, DisplacementProbe, Frame, LoadingStage
from drivers.safety import ForceGuard, StaleReadingGuard
from rigctl.acquisition.clockmap import ClockMap
from rigctl.acquisition.publisher import Publisher
from rigctl.status import RunStatus
from rigctl.storage import RunWriter

_log = logging.getLogger(__name__)

STAGE_RETRY_S = 1.0
"""A stage whose position read failed is asked again after this long (each failed read costs
its command timeout, which would slow the force recording)."""
_QUEUE_PUT_TIMEOUT_S = 0.5
_FRAME_BATCH = 32
"""Most consecutive frames written in one call."""
FRAME_ROOM_WAIT_S = 0.5
"""Longest a frame waits for room in the writer's queue (its share of frames full) before it is
dropped and counted: a camera keeps its own buffer meanwhile (a real one about 2 s at 60 Hz)."""
_IN_RANGE_HOLD_S = 1.0
"""A probe is back in range after this long without an over-range sample."""
"""Most consecutive frames written in one call."""
_POLLS_KEPT = 64
"""Stage-position polls kept to interpolate a block's samples between (one per block)."""
_HISTORY_CHANNELS = ("ft_N", "fn_N", "d1_m", "d2_m", "x_stage_m", "z_stage_m")


@dataclass
class RigDevices:
    """The devices a procedure and the acquisition use, behind the drivers' interfaces."""

    tangential_stage: LoadingStage
    normal_stage: LoadingStage
    daq: Daq
    camera: Camera | None = None
    d1: DisplacementProbe | None = None
    d2: DisplacementProbe | None = None
    device_now_s: Callable[[], float] | None = None
    """The DAQ's device time of the present instant, where the rig can tell (NaN: not yet): a
    simulated rig's clock, which a paced rig runs up to ``Pacer.max_lag_s`` ahead of the recorded
    data. None (the hardware): the newest recorded sample's time, which the DAQ delivers within its
    transport delay (milliseconds)."""

    @classmethod
    def from_device_set(
        cls, devices: Any, device_now_s: Callable[[], float] | None = None
    ) -> RigDevices:
        """From any object with the six device attributes (e.g. sim_devices' DeviceSet)."""
        return cls(
            devices.tangential_stage, devices.normal_stage, devices.daq,
            getattr(devices, "camera", None), getattr(devices, "d1", None),
            getattr(devices, "d2", None), device_now_s,
        )


@dataclass
class AcquisitionStats:
    """Counts and lags of a session (all drops counted, none hidden)."""

    daq_samples: int = 0
    daq_blocks: int = 0
    daq_dropped: int = 0
    """Samples the DAQ's counter says were lost before reaching the host."""
    frames: int = 0
    frames_dropped: int = 0
    """Camera frames lost (sequence gaps, late frames)."""
    frames_unplaced: int = 0
    """Frames whose time the clock map could not place (host-stamped frames are held until the
    first DAQ block fits it)."""
    queue_dropped_samples: int = 0
    """Samples refused because the writer queue stayed full (the writer could not keep up)."""
    queue_dropped_frames: int = 0
    subscriber_dropped: int = 0
    writer_lag_max_s: float = 0.0
    """Longest host time between a block's arrival and its hand-over to the run file."""
    writer_lag_last_s: float = 0.0
    """The same for the latest block."""
    events: int = 0
    probe_over_range_samples: dict[str, int] = field(default_factory=dict)
    """Samples per probe channel whose analog output sat at the rail (recorded as read, marked)."""
    errors: list[str] = field(default_factory=list)


class Acquisition:
    """Concurrent acquisition into one run file (or none, for monitoring only)."""

    def __init__(
        self,
        devices: RigDevices,
        writer: RunWriter | None,
        *,
        block_samples: int = 1024,
        record_camera: bool = True,
        force_guard: ForceGuard | None = None,
        stale_guard: StaleReadingGuard | None = None,
        history_s: float = 10.0,
        queue_items: int = 4096,
        max_queued_frames: int = 240,
        publisher: Publisher | None = None,
    ) -> None:
        if block_samples < 1:
            raise ValueError("block_samples must be >= 1")
        self.devices = devices
        self.writer = writer
        self.block_samples = int(block_samples)
        self.record_camera = (
            record_camera
            and devices.camera is not None
            and (writer is None or writer.camera is not None)  # only into a file with a camera stream
        )
        self.force_guard = force_guard
        self.stale_guard = stale_guard
        self._stage_retry_at: dict[str, float] = {}
        self.publisher = publisher or Publisher()
        self.clock = ClockMap()
        self.stats = AcquisitionStats()
        self._queue: queue.Queue[tuple[Any, ...]] = queue.Queue(maxsize=queue_items)
        self.max_queued_frames = int(max_queued_frames)
        self._queued_frames = 0
        self._stop = threading.Event()
        self._writer_stop = threading.Event()
        self._fault = threading.Event()
        self._error: BaseException | None = None
        self._lock = threading.Lock()
        self._new_data = threading.Condition(self._lock)
        self._frame_room = threading.Condition(self._lock)
        n_hist = max(16, int(history_s * devices.daq.rate_hz))
        self._hist_t: deque[np.ndarray] = deque()
        self._hist: dict[str, deque[np.ndarray]] = {c: deque() for c in _HISTORY_CHANNELS}
        self._hist_len = 0
        self._hist_max = n_hist
        self._t_s = float("nan")
        self._latest: dict[str, float] = {}
        self._polls: deque[tuple[float, float, float]] = deque(maxlen=_POLLS_KEPT)
        self._last_dropped_total = 0
        self._over_range: dict[str, bool] = {}
        self._in_range_run: dict[str, int] = {}
        self._threads: list[threading.Thread] = []
        self._final_status: tuple[RunStatus, str | None] = (RunStatus.COMPLETED, None)
        self._started = False
        self._camera_start_error: BaseException | None = None

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> Acquisition:
        """Start the DAQ stream and the camera together, then the threads.

        The camera starts here, right after the DAQ, not in its thread: a thread may be scheduled
        late on a busy machine, and a simulated rig paced against the recorder runs on meanwhile,
        so the first frames would come up to a second after the first samples. Its frames are read
        as they come; those stamped only by the host wait for the first DAQ block (the clock map
        places them). A camera that does not start fails the run as one that stops answering does
        (:meth:`check`)."""
        if self._started:
            return self
        self._started = True
        self.devices.daq.start()
        if self.record_camera:
            cam = self.devices.camera
            assert cam is not None
            try:
                cam.start()
            except Exception as exc:  # reported by the camera thread, the DAQ records on
                self._camera_start_error = exc
        targets = [(self._daq_loop, "acq-daq"), (self._writer_loop, "acq-writer")]
        if self.record_camera:
            targets.append((self._camera_loop, "acq-camera"))
        for target, name in targets:
            th = threading.Thread(target=target, name=name, daemon=True)
            th.start()
            self._threads.append(th)
        return self

    def stop(
        self, status: RunStatus = RunStatus.COMPLETED, error: str | None = None
    ) -> AcquisitionStats:
        """Stop the readers, write everything queued, close the run file with ``status``."""
        self._final_status = (status, error)
        self._stop.set()
        for th in self._threads:
            if th.name != "acq-writer":
                th.join(timeout=5.0)
        self._writer_stop.set()
        for th in self._threads:
            if th.name == "acq-writer":
                th.join(timeout=30.0)
        for name, stop in (("daq", self.devices.daq.stop), ("camera", self._stop_camera)):
            try:
                stop()
            except Exception as exc:  # a dead device must not keep the file open
                _log.warning("stopping %s failed: %s", name, exc)
        self.stats.subscriber_dropped = self.publisher.dropped
        return self.stats

    def _stop_camera(self) -> None:
        cam = self.devices.camera
        if self.record_camera and cam is not None and cam.running:
            cam.stop()

    def check(self) -> None:
        """Re-raise the first error any acquisition thread met (a device stopped answering...)."""
        if self._error is not None:
            raise self._error

    @property
    def faulted(self) -> threading.Event:
        """Set when a thread failed (wait on it to react within milliseconds)."""
        return self._fault

    def _fail(self, exc: BaseException, where: str) -> None:
        if self._stop.is_set() and where in ("daq", "camera"):
            # a reader interrupted by the shutdown itself (e.g. no frame while stopping): noted only
            self.stats.errors.append(f"{where} (while stopping): {exc}")
            return
        with self._lock:
            if self._error is None:
                self._error = exc
            self.stats.errors.append(f"{where}: {exc}")
            self._new_data.notify_all()
        self._fault.set()
        _log.error("acquisition %s failed: %s", where, exc)

    # ------------------------------------------------------------------ readings for procedures
    @property
    def t_s(self) -> float:
        """Device time of the latest sample [s] (NaN before the first block)."""
        return self._t_s

    def device_now_s(self) -> float:
        """Device time of the present instant [s]: what the devices are doing now (a stage that just
        stopped, a step that starts) happens at this time on the recorded axis.

        The newest sample's time, or later where the rig says its clock is ahead of the recorded
        data (:attr:`RigDevices.device_now_s`: a simulated rig paced ahead of the recorder). NaN
        before the first block."""
        t = self._t_s
        clock = self.devices.device_now_s
        if clock is not None:
            ahead = float(clock())
            if ahead > t:  # False for NaN either side
                return ahead
        return t

    def latest(self) -> dict[str, float]:
        with self._lock:
            return dict(self._latest)

    def mean(self, channel: str, duration_s: float) -> float:
        """Mean of a channel over the last ``duration_s`` of device time."""
        with self._lock:
            if not self._hist_t:
                return float("nan")
            t = np.concatenate(list(self._hist_t))
            v = np.concatenate(list(self._hist[channel]))
        m = t >= t[-1] - duration_s
        return float(np.mean(v[m]))

    def wait_until(self, t_s: float, timeout_s: float, stop: threading.Event | None = None) -> bool:
        """Wait until device time reaches ``t_s``; False on timeout, on ``stop`` or a fault."""
        deadline = time.monotonic() + timeout_s
        with self._new_data:
            while not (self._t_s >= t_s):
                if self._error is not None or (stop is not None and stop.is_set()):
                    return False
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._new_data.wait(min(left, 0.05))
        return True

    def catch_up(self, timeout_s: float) -> bool:
        """Wait until the recorded data reach the present device instant (:meth:`device_now_s`):
        called before :meth:`stop`, so that what the devices did up to the end of a protocol (a
        return move that just finished, the last step marker) is in the record. On a paced
        simulated rig, or with a reader behind the DAQ, the newest sample can be that far behind.
        False on timeout (host seconds), a fault, or no data at all."""
        now = self.device_now_s()
        if not math.isfinite(now):
            return False
        return self.wait_until(now, timeout_s)

    @property
    def queue_depth(self) -> int:
        """Items waiting for the writer (blocks, frames, events)."""
        return self._queue.qsize()

    def mark(self, name: str, message: str = "") -> None:
        """A step marker at the present device time (:meth:`device_now_s`; written in order with
        the data)."""
        now = self.device_now_s()
        t = now if np.isfinite(now) else 0.0
        self._put(("event", t, name, message), samples=0, frames=0)
        self.stats.events += 1

    # ------------------------------------------------------------------ threads
    def _put(self, item: tuple[Any, ...], samples: int, frames: int) -> None:
        try:
            self._queue.put(item, timeout=_QUEUE_PUT_TIMEOUT_S)
        except queue.Full:
            self.stats.queue_dropped_samples += samples
            self.stats.queue_dropped_frames += frames
            if frames:
                with self._frame_room:
                    self._queued_frames -= frames
                    self._frame_room.notify_all()
            _log.error("writer queue full: %d samples / %d frames dropped", samples, frames)

    def _daq_loop(self) -> None:
        try:
            while not self._stop.is_set():
                block = self.devices.daq.read_block(self.block_samples, timeout_s=0.5)
                if block.counter.shape[0] == 0:
                    continue
                self._handle_block(block)
        except BaseException as exc:
            self._fail(exc, "daq thread (forces, probes, stage positions)")

    def _positions(self) -> tuple[float, float]:
        """Both stage positions; a stage that does not answer gives NaN (a missing value) and is
        asked again only after STAGE_RETRY_S, so that a dead or corrupting stage never stops the
        force recording (the safe state's release is recorded through to the end)."""
        return (self._position("tangential", self.devices.tangential_stage),
                self._position("normal", self.devices.normal_stage))

    def _positions_at(self, t: np.ndarray, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Both stage positions at the block's sample times ``t`` (last ``t1``).

        The positions are polled now. A poll is placed at the device time it was made (the mean
        of :meth:`device_now_s` before and after it, never before the block's last sample), and
        each sample gets the line between the polls around it (the first poll's value before it).
        On a paced simulated rig the rig runs ahead of the recorded data, so a poll placed at the
        block's last sample would put each position up to the pacer's lag too early."""
        before = self.device_now_s()
        x1, z1 = self._positions()
        after = self.device_now_s()
        t_poll = max(0.5 * (before + after), t1) if after == after and before == before else t1
        if self._polls and t_poll <= self._polls[-1][0]:
            self._polls.pop()  # polls stay in time order (the newest wins a tie)
        self._polls.append((t_poll, x1, z1))
        if len(self._polls) == 1:
            return np.full(t.shape, x1), np.full(t.shape, z1)
        tp, xp, zp = (np.array(c) for c in zip(*self._polls, strict=True))
        return np.interp(t, tp, xp), np.interp(t, tp, zp)

    def _position(self, key: str, stage: Any) -> float:
        now = time.monotonic()
        if now < self._stage_retry_at.get(key, 0.0):
            return math.nan
        try:
            x = float(stage.position_m())
        except Exception as exc:
            first = key not in self._stage_retry_at
            self._stage_retry_at[key] = now + STAGE_RETRY_S
            if first:
                self.stats.errors.append(f"{key} stage position unavailable: {exc}")
                _log.error("%s stage position unavailable (recorded as NaN): %s", key, exc)
            return math.nan
        self._stage_retry_at.pop(key, None)
        return x

    def _handle_block(self, block: DaqBlock) -> None:
        cmap = self.devices.daq.channel_map
        t = block.t_s
        t1 = float(t[-1])
        xs, zs = self._positions_at(t, t1)
        columns = {
            "t_s": t,
            "ft_N": cmap.ft_N(block),
            "fn_N": cmap.fn_N(block),
            "fx_N": block.fx_N,
            "fy_N": block.fy_N,
            "fz_N": block.fz_N,
            "d1_m": cmap.d1_m(block),
            "d2_m": cmap.d2_m(block),
            "x_stage_m": xs,
            "z_stage_m": zs,
        }
        if self.force_guard is not None:
            trip = self.force_guard.feed(columns["fn_N"])
            if trip is not None:
                self._fail(trip, "force guard")
        if self.stale_guard is not None:
            frozen = self.stale_guard.feed(t, (block.fx_N, block.fy_N, block.fz_N))
            if frozen is not None:
                # halt before the fault is raised: the procedure's safe state (the load release)
                # follows the fault, and a halt after it would stop the release half-way
                self.stale_guard.halt()
                self._fail(frozen, "DAQ watchdog")
        dropped = int(block.dropped_total - self._last_dropped_total)
        self._last_dropped_total = int(block.dropped_total)
        n = int(t.shape[0])
        self.clock.add(block.host_monotonic_ns, t1)
        with self._new_data:
            self._hist_t.append(t)
            for c in _HISTORY_CHANNELS:
                self._hist[c].append(columns[c])
            self._hist_len += n
            while self._hist_len - self._hist_t[0].shape[0] >= self._hist_max:
                self._hist_len -= self._hist_t.popleft().shape[0]
                for c in _HISTORY_CHANNELS:
                    self._hist[c].popleft()
            self._t_s = t1
            self._latest = {c: float(columns[c][-1]) for c in _HISTORY_CHANNELS}
            self._latest["t_s"] = t1
            self.stats.daq_samples += n
            self.stats.daq_blocks += 1
            self.stats.daq_dropped += dropped
            self._new_data.notify_all()
        self.publisher.publish("daq", columns)
        self._put(
            ("daq", columns, int(block.counter[0]), time.monotonic(), block.host_monotonic_ns * 1e-9,
             dropped),
            samples=n, frames=0,
        )
        self._mark_probe_range(cmap.probe_over_range(block), t)

    def _mark_probe_range(self, masks: dict[str, np.ndarray], t: np.ndarray) -> None:
        """Count over-range probe samples; mark entries into over range and returns from it.

        A return is marked only after ``_IN_RANGE_HOLD_S`` of in-range samples, so a probe hovering
        at the edge of its range (stick-slip there) gives one event, not one per cycle.
        """
        hold = max(1, int(_IN_RANGE_HOLD_S * self.devices.daq.rate_hz))
        for channel, mask in masks.items():
            over_idx = np.flatnonzero(mask)
            if over_idx.size:
                self.stats.probe_over_range_samples[channel] = (
                    self.stats.probe_over_range_samples.get(channel, 0) + int(over_idx.size)
                )
            over = self._over_range.get(channel, False)
            run = self._in_range_run.get(channel, 0)  # in-range samples since the last over-range one
            if not over and over_idx.size:
                k = int(over_idx[0])
                text = (f"{channel}: probe over range (analog output at the rail; the recorded "
                        "value is the rail, not a displacement)")
                _log.warning("%s at t = %.3f s", text, float(t[k]))
                self._put(("event", float(t[k]), "probe_over_range", text), samples=0, frames=0)
                self.stats.events += 1
                over = True
            if over:
                run = mask.size - 1 - int(over_idx[-1]) if over_idx.size else run + mask.size
                if run >= hold:
                    k = max(mask.size - run, 0)  # the first in-range sample (or this block's start)
                    self._put(("event", float(t[k]), "probe_in_range", f"{channel}: back in range"),
                              samples=0, frames=0)
                    self.stats.events += 1
                    over = False
            self._over_range[channel] = over
            self._in_range_run[channel] = run

    def _camera_loop(self) -> None:
        cam = self.devices.camera
        assert cam is not None
        try:
            if self._camera_start_error is not None:
                raise self._camera_start_error
            last_t = -np.inf
            early: deque[Frame] = deque()  # host-stamped frames read before the DAQ clock map
            while not self._stop.is_set():
                frame = cam.read_frame(timeout_s=1.0)  # DeviceTimeout: the camera stopped answering
                if not math.isfinite(frame.t_device_s) and not self.clock.ready:
                    # placed once the first DAQ block fits the clock map; at most a queue's share
                    if len(early) >= self.max_queued_frames:
                        early.popleft()
                        self.stats.queue_dropped_frames += 1
                    early.append(frame)
                    continue
                while early:
                    last_t = self._queue_frame(early.popleft(), last_t)
                last_t = self._queue_frame(frame, last_t)
        except DeviceTimeout as exc:
            if not self._stop.is_set():  # no frame while recording: the camera stopped answering
                self._fail(exc, "camera")
            # no frame while the session stops is only the end of the stream
        except BaseException as exc:
            self._fail(exc, "camera")

    def _queue_frame(self, frame: Frame, last_t: float) -> float:
        """Place ``frame`` on the DAQ's time axis, publish it and queue it for the writer; the
        newest frame time so far (frames whose time cannot be placed are counted, not queued)."""
        # a camera synchronised to the DAQ gives its frame's device time; else the host instant is
        # placed through the clock map
        t = (frame.t_device_s if math.isfinite(frame.t_device_s)
             else self.clock.device_time(frame.t_monotonic_ns))
        if not np.isfinite(t):
            self.stats.frames_unplaced += 1
            return last_t
        t = max(t, last_t + 1e-6)  # the clock fit may move; keep frame times increasing
        self.stats.frames += 1
        self.stats.frames_dropped += int(frame.dropped_before)
        self.publisher.publish("camera", (t, frame))
        with self._frame_room:
            # frames are big: their share of the buffer is bounded; a full share waits a little
            # for the writer (a paced simulated rig waits with the camera) before the frame is
            # dropped
            self._frame_room.wait_for(
                lambda: self._queued_frames < self.max_queued_frames or self._stop.is_set(),
                timeout=FRAME_ROOM_WAIT_S)
            full = self._queued_frames >= self.max_queued_frames
            if not full:
                self._queued_frames += 1
        if full:
            self.stats.queue_dropped_frames += 1
            return t
        self._put(("frame", frame.image, t, frame.seq, time.monotonic()), samples=0, frames=1)
        return t

    def _writer_loop(self) -> None:
        w = self.writer
        failure: BaseException | None = None
        held: tuple[Any, ...] | None = None  # an item taken while gathering frames
        try:
            while True:
                if held is not None:
                    item, held = held, None
                else:
                    try:
                        item = self._queue.get(timeout=0.05)
                    except queue.Empty:
                        if self._writer_stop.is_set():
                            break
                        if w is not None:
                            w.maybe_flush()
                        continue
                if item[0] == "frame":
                    with self._frame_room:
                        self._queued_frames -= 1
                        self._frame_room.notify_all()
                if w is None:
                    continue
                kind = item[0]
                if kind == "daq":
                    _, columns, counter, arrived, host_s, dropped = item
                    w.append_daq(columns, counter=counter, host_time_s=host_s, dropped=dropped)
                    lag = time.monotonic() - arrived
                    self.stats.writer_lag_last_s = lag
                    self.stats.writer_lag_max_s = max(self.stats.writer_lag_max_s, lag)
                elif kind == "frame":
                    # consecutive frames go in one write (one resize): what keeps up at high rates
                    batch = [item]
                    while len(batch) < _FRAME_BATCH:
                        try:
                            nxt = self._queue.get_nowait()
                        except queue.Empty:
                            break
                        if nxt[0] != "frame":
                            held = nxt
                            break
                        with self._frame_room:
                            self._queued_frames -= 1
                            self._frame_room.notify_all()
                        batch.append(nxt)
                    w.append_frames(np.stack([b[1] for b in batch]), [b[2] for b in batch],
                                    [b[3] for b in batch])
                elif kind == "event":
                    _, t, name, message = item
                    w.add_event(t, name, message)
                w.maybe_flush()  # on time even while the queue never runs empty
        except BaseException as exc:
            failure = exc
            self._fail(exc, "writer")
        finally:
            if w is not None and not w.closed:
                status, error = self._final_status
                if failure is not None:
                    status, error = RunStatus.FAILED, f"run file writer: {failure}"
                try:
                    w.close(status, error)
                except Exception as exc:
                    _log.error("closing the run file failed: %s", exc)
