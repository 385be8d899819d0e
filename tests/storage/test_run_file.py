"""RunWriter / RunReader: the layout of docs/run-file.md, statuses, validation, no lost data."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.storage import (
    DEFAULT_DAQ_CHANNELS,
    CameraLayout,
    DaqLayout,
    RunDescription,
    RunReader,
    RunWriter,
    StorageError,
    read_run,
)
from rigctl.storage import writer as writer_module
from tests.storage.conftest import block

DESC = RunDescription(
    protocol="tlre",
    parameters={"fn_N": 300.0, "velocity_m_s": 1e-5},
    operator="Han",
    notes="first run",
    config_toml='[rig]\nbackend = "sim"\n',
    calibration={"force_N_per_count": 0.02},
    metadata={"sample_rate_hz": "1024", "specimen": "PMMA boss"},
)
CAMERA = CameraLayout(height_px=12, width_px=16, frame_rate_hz=60.0)


def _record(path: Path, n_blocks: int = 10, block_n: int = 64) -> None:
    with RunWriter(path, DESC, camera=CAMERA) as w:
        w.add_event(0.0, "load", "normal stage to 300 N")
        for k in range(n_blocks):
            w.append_daq(
                block(k * block_n, block_n),
                counter=k * block_n + 7,
                host_time_s=100.0 + k,
                dropped=2 if k == 4 else 0,
            )
        w.append_frames(np.full((3, 12, 16), 9, np.uint8), [0.0, 1 / 60, 3 / 60], [0, 1, 3])
        w.add_event(0.5, "slide", "v = 10 um/s")


def test_everything_written_is_read_back(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    _record(path)
    with RunReader(path) as r:
        assert r.status == "completed"
        assert r.n_samples == 640
        data = r.read_daq()
        expected = block(0, 640)
        for name in ("t_s", *DEFAULT_DAQ_CHANNELS):
            np.testing.assert_array_equal(data[name], expected[name], err_msg=name)
        assert r.channels == {
            "ft_N": "N",
            "fn_N": "N",
            "fx_N": "N",
            "fy_N": "N",
            "fz_N": "N",
            "d1_m": "m",
            "d2_m": "m",
            "x_stage_m": "m",
            "z_stage_m": "m",
        }
        assert r.protocol == "tlre"
        assert r.parameters == {"fn_N": 300.0, "velocity_m_s": 1e-5}
        assert r.calibration == {"force_N_per_count": 0.02}
        assert r.config_toml == DESC.config_toml
        assert r.metadata == DESC.metadata
        assert [(e.t_s, e.name, e.message) for e in r.events()] == [
            (0.0, "load", "normal stage to 300 N"),
            (0.5, "slide", "v = 10 um/s"),
        ]
        frames, t, seq = r.frames()
        assert frames.shape == (3, 12, 16) and frames.dtype == np.uint8 and (frames == 9).all()
        np.testing.assert_array_equal(seq, [0, 1, 3])
        np.testing.assert_array_equal(t, [0.0, 1 / 60, 3 / 60])
        s = r.summary()
        assert (s.n_frames, s.dropped_frames, s.dropped_samples, s.n_events) == (3, 1, 2, 2)
        assert s.duration_s == pytest.approx(639 / 1024)
        assert s.operator == "Han" and s.notes == "first run"
        assert set(s.software) >= {"rigctl", "numpy", "h5py", "hdf5", "python"}
        assert s.start_time < s.end_time  # ISO 8601, same offset
    run = read_run(path)
    np.testing.assert_array_equal(run.ft_N, block(0, 640)["ft_N"])
    assert list(run.extra) == ["fx_N", "fy_N", "fz_N", "z_stage_m"]


def test_layout_is_nexus_and_swmr_ready(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    _record(path)
    with h5py.File(path, "r") as f:
        assert f.attrs["default"] == "entry"
        entry = f["entry"]
        assert entry.attrs["NX_class"] == "NXentry"
        assert entry.attrs["default"] == "plot"
        assert entry["definition"][()].decode() == "rigctl_run"
        plot = entry["plot"]
        assert plot.attrs["NX_class"] == "NXdata"
        assert plot.attrs["signal"] == "ft_N"
        assert list(plot.attrs["axes"]) == ["time"]
        assert plot["ft_N"].id == entry["daq/ft_N"].id  # the same dataset, linked
        daq = entry["daq"]
        assert daq.attrs["NX_class"] == "NXlog"
        assert daq["time"].attrs["units"] == "s"
        assert daq["time"].attrs["start"] == entry["start_time"][()].decode()
        for name in DEFAULT_DAQ_CHANNELS:
            assert daq[name].chunks is not None and daq[name].maxshape == (None,)
            assert daq[name].attrs["units"] in ("N", "m")
        np.testing.assert_array_equal(daq["blocks/first_sample"][:], np.arange(10) * 64)
        np.testing.assert_array_equal(daq["blocks/counter"][:], np.arange(10) * 64 + 7)
        np.testing.assert_array_equal(daq["blocks/host_time"][:], 100.0 + np.arange(10))
        assert daq["blocks/host_time"].attrs["units"] == "s"
        frames = entry["camera/frames"]
        assert frames.chunks == (1, 12, 16) and frames.compression == "gzip"
        assert f.id.get_create_plist().get_version()[0] == 3  # superblock v3: the v110 format
        assert json.loads(entry["protocol/parameters"][()]) == DESC.parameters


def test_exception_inside_the_run_records_failed_and_keeps_data(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with pytest.raises(RuntimeError, match="stage alarm"), RunWriter(path, DESC) as w:
        w.append_daq(block(0, 100))
        w.append_daq(block(100, 50))
        raise RuntimeError("stage alarm 3: over-load")
    with RunReader(path) as r:
        assert r.status == "failed"
        assert r.summary().error == "RuntimeError: stage alarm 3: over-load"
        assert r.n_samples == 150  # pending samples were written on the way out


def test_keyboard_interrupt_records_aborted(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with pytest.raises(KeyboardInterrupt), RunWriter(path, DESC) as w:
        w.append_daq(block(0, 10))
        raise KeyboardInterrupt
    with RunReader(path) as r:
        assert r.status == "aborted"
        assert r.n_samples == 10


def test_tiny_blocks_are_coalesced_and_nothing_is_lost(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with RunWriter(path, DESC, DaqLayout(channels=("ft_N",))) as w:
        for i in range(3000):
            w.append_daq(block(i, 1, ("ft_N",)))
        assert w.n_samples == 3000
    with RunReader(path) as r:
        np.testing.assert_array_equal(r.read_daq()["ft_N"], np.arange(3000.0))
        blocks = r.blocks()
        assert blocks["first_sample"].tolist() == list(range(3000))
        assert (blocks["counter"] == -1).all() and np.isnan(blocks["host_time_s"]).all()


def test_nan_values_are_recorded_but_bad_blocks_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with RunWriter(path, DESC) as w:
        good = block(0, 4)
        good["d1_m"][2] = np.nan  # a probe over range: recorded as it came
        w.append_daq(good)
        missing = block(4, 4)
        del missing["d2_m"]
        with pytest.raises(DataError, match="missing \\['d2_m'\\]"):
            w.append_daq(missing)
        with pytest.raises(DataError, match="unknown \\['temp_C'\\]"):
            w.append_daq(block(4, 4) | {"temp_C": np.zeros(4)})
        short = block(4, 4)
        short["ft_N"] = short["ft_N"][:3]
        with pytest.raises(DataError, match="shape"):
            w.append_daq(short)
        with pytest.raises(DataError, match="increase strictly"):
            w.append_daq(block(3, 4))  # overlaps the last block
        nan_time = block(4, 4)
        nan_time["t_s"][1] = np.nan
        with pytest.raises(DataError, match="finite"):
            w.append_daq(nan_time)
        with pytest.raises(StorageError, match="without a camera"):
            w.append_frames(np.zeros((1, 12, 16), np.uint8), [0.0], [0])
        w.append_daq(block(4, 4))
    run = read_run(path, validate=False)
    assert run.n_samples == 8 and np.isnan(run.d1_m[2])
    with pytest.raises(DataError, match="NaN"):
        read_run(path)


def test_frames_of_the_wrong_kind_are_refused(tmp_path: Path) -> None:
    with RunWriter(tmp_path / "run.h5", DESC, camera=CAMERA) as w:
        with pytest.raises(DataError, match="uint8"):
            w.append_frames(np.zeros((1, 12, 16), np.uint16), [0.0], [0])
        with pytest.raises(DataError, match="shape"):
            w.append_frames(np.zeros((1, 16, 12), np.uint8), [0.0], [0])
        with pytest.raises(DataError, match="times"):
            w.append_frames(np.zeros((2, 12, 16), np.uint8), [0.0], [0])
        w.append_frames(np.zeros((12, 16), np.uint8), 0.0, 0)  # one frame alone is fine
        assert w.n_frames == 1


def test_one_writer_thread_only(tmp_path: Path) -> None:
    errors: list[BaseException] = []
    with RunWriter(tmp_path / "run.h5", DESC) as w:
        w.append_daq(block(0, 4))

        def other() -> None:
            try:
                w.append_daq(block(4, 4))
            except BaseException as exc:
                errors.append(exc)

        t = threading.Thread(target=other)
        t.start()
        t.join()
    assert len(errors) == 1 and isinstance(errors[0], RuntimeError)


def test_flush_happens_on_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [1000.0]
    monkeypatch.setattr(writer_module.time, "monotonic", lambda: clock[0])
    path = tmp_path / "run.h5"
    w = RunWriter(path, DESC, flush_interval_s=0.25)
    try:
        w.append_daq(block(0, 64))
        with RunReader(path) as r:
            assert r.n_samples == 0  # coalescing: not yet written
        clock[0] += 0.2
        assert not w.maybe_flush()
        clock[0] += 0.06
        assert w.maybe_flush()  # 0.26 s since the last flush
        with RunReader(path) as r:
            assert r.n_samples == 64
    finally:
        w.close()
    with pytest.raises(ValueError, match="flush_interval_s"):
        RunWriter(tmp_path / "x.h5", DESC, flush_interval_s=1.0)


def test_long_texts_are_truncated_visibly(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with RunWriter(path, DESC) as w:
        w.add_event(0.0, "n" * 100, "é" * 1000)
        w.close("failed", "x" * 10_000)
    with RunReader(path) as r:
        event = r.events()[0]
        assert event.name.endswith("[truncated]") and len(event.name.encode()) <= 64
        assert event.message.endswith("[truncated]") and event.message.startswith("é")
        assert r.summary().error.endswith("[truncated]")


def test_close_is_idempotent_and_checks_status(tmp_path: Path) -> None:
    w = RunWriter(tmp_path / "run.h5", DESC)
    with pytest.raises(ValueError, match="status"):
        w.close("finished")
    w.close("aborted", "operator stop")
    w.close("completed")
    assert w.status == "aborted"
    with pytest.raises(StorageError, match="closed"):
        w.append_daq(block(0, 1))


def test_unusable_output_paths_fail_before_anything_starts(tmp_path: Path) -> None:
    with pytest.raises(StorageError, match="does not exist"):
        RunWriter(tmp_path / "missing" / "run.h5", DESC)
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(StorageError, match="is not a folder"):
        RunWriter(a_file / "run.h5", DESC)
    with pytest.raises(StorageError, match="already exists"):
        RunWriter(a_file, DESC)
    with pytest.raises(StorageError, match="not enough free space"):
        RunWriter(tmp_path / "big.h5", DESC, camera=CAMERA, expected_duration_s=1e15)
    with pytest.raises(StorageError, match="not enough free space"):
        RunWriter(tmp_path / "big.h5", DESC, min_free_bytes=2**62)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into any folder")
def test_unwritable_folder_fails_before_anything_starts(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(StorageError, match="not writable"):
            RunWriter(locked / "run.h5", DESC)
    finally:
        locked.chmod(0o700)


def test_non_run_files_are_refused_clearly(tmp_path: Path) -> None:
    text = tmp_path / "x.h5"
    text.write_text("hello")
    with pytest.raises(DataError, match="not an HDF5 file"):
        RunReader(text)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["data"] = np.arange(3)
    with pytest.raises(DataError, match="not a rigctl run file"):
        RunReader(other)
    with pytest.raises(DataError, match="no such file"):
        RunReader(tmp_path / "absent.h5")


def test_a_run_without_required_channels_cannot_become_a_measured_run(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with RunWriter(path, DESC, DaqLayout(channels=("ft_N", "fn_N"))) as w:
        w.append_daq(block(0, 4, ("ft_N", "fn_N")))
    with pytest.raises(DataError, match="no channel\\(s\\) x_stage_m, d1_m, d2_m"):
        read_run(path)


def test_a_failed_write_keeps_the_samples_for_the_next_attempt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.h5"
    real_write_at = writer_module._write_at
    calls = {"n": 0}

    def flaky(dataset: h5py.Dataset, start: int, values: np.ndarray) -> None:
        calls["n"] += 1
        if calls["n"] == 3:  # fails after two datasets were already written
            raise OSError(5, "Input/output error")
        real_write_at(dataset, start, values)

    monkeypatch.setattr(writer_module, "_write_at", flaky)
    with RunWriter(path, DESC) as w:
        w.append_daq(block(0, 100))
        with pytest.raises(StorageError, match="Input/output error"):
            w.flush()
        assert w.n_samples == 100  # still pending, not lost
        w.append_daq(block(100, 28))
    with RunReader(path) as r:
        np.testing.assert_array_equal(r.read_daq()["fz_N"], block(0, 128)["fz_N"])
        assert r.blocks()["first_sample"].tolist() == [0, 100]


def test_a_filling_disk_stops_the_recording_while_the_file_can_still_be_closed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = [1000.0]
    free = [10 * 2**30]
    monkeypatch.setattr(writer_module.time, "monotonic", lambda: clock[0])
    real_usage = writer_module.shutil.disk_usage
    monkeypatch.setattr(
        writer_module.shutil, "disk_usage",
        lambda p: real_usage(p)._replace(free=free[0]),
    )
    path = tmp_path / "run.h5"
    w = RunWriter(path, DESC, min_free_bytes=64 * 2**20)
    w.append_daq(block(0, 64))
    clock[0] += writer_module.DISK_CHECK_INTERVAL_S
    assert w.maybe_flush()  # plenty of room
    free[0] = 20 * 2**20  # 20 MiB left: below half the 64 MiB reserve
    w.append_daq(block(64, 64))
    clock[0] += writer_module.DISK_CHECK_INTERVAL_S
    with pytest.raises(StorageError, match=r"disk nearly full: 20\.0 MiB free"):
        w.maybe_flush()
    w.close("failed", "disk nearly full")
    with RunReader(path) as r:
        assert r.status == "failed"
        assert r.n_samples == 128  # nothing appended was lost
