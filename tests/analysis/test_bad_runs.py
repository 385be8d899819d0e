"""Malformed, truncated and frameless runs: a clear one-line error or a report saying what is missing."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.analysis.pipeline import analyse_campaign, analyse_run
from rigctl.analysis.report import write_report
from rigctl.cli.main import main
from rigctl.io.csv_format import write_csv
from rigctl.storage import RunWriter
from rigctl.storage.convert import write_measured_run
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from tests.workbench.synth import sawtooth_run

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def saw():
    run, slips = sawtooth_run(duration_s=20.0, t_load_start_s=1.0, seed=5)
    return run, slips


def _with_frames(path: Path, run, n_frames: int = 30) -> Path:
    cols = run.columns()
    daq = DaqLayout(channels=tuple(k for k in cols if k != "t_s"))
    cam = CameraLayout(height_px=24, width_px=32, frame_rate_hz=1.0)
    with RunWriter(path, RunDescription(protocol="tlre"), daq, cam, min_free_bytes=0) as w:
        w.append_daq(cols)
        t = np.linspace(0.5, float(run.t_s[-1]) - 0.5, n_frames)
        w.append_frames(np.full((n_frames, 24, 32), 9, np.uint8), t, np.arange(n_frames))
    return path


@pytest.mark.slow
def test_csv_gets_mechanics_and_names_the_image_analyses_it_cannot_do(saw, tmp_path):
    run, slips = saw
    csv = tmp_path / "other_rig.csv"
    write_csv(csv, run)
    ra = analyse_run(csv)
    assert len(ra.mechanics.passes) == 1
    assert ra.mechanics.passes[0].cycles.n == len(slips)
    note = " ".join(ra.notes)
    assert "CSV run has no camera frames" in note and "Isum(t)" in note and "CSI" in note
    index, js = write_report(analyse_campaign([csv]), tmp_path / "rep")
    assert "Isum(t)" in index.read_text()
    assert json.loads(js.read_text())["runs"][0]["passes"][0]["n_cycles"] == len(slips)


def test_run_file_without_camera_says_so(saw, tmp_path):
    run, _ = saw
    p = write_measured_run(tmp_path / "nocam.h5", run)
    ra = analyse_run(p)
    assert any("no camera stream" in n for n in ra.notes)
    assert ra.mechanics.passes


def test_frames_without_times(saw, tmp_path):
    run, _ = saw
    p = _with_frames(tmp_path / "notimes.h5", run)
    with h5py.File(p, "r+") as f:
        f["entry/camera/time"].resize((0,))
    ra = analyse_run(p)
    assert any("30 frames but no frame times" in n for n in ra.notes)
    assert ra.source.frames is None
    assert ra.mechanics.passes  # the mechanics are still there


def test_frames_partly_without_times(saw, tmp_path):
    run, _ = saw
    p = _with_frames(tmp_path / "some.h5", run)
    with h5py.File(p, "r+") as f:
        f["entry/camera/time"].resize((20,))
    ra = analyse_run(p)
    assert ra.source.frames is not None and ra.source.frames.n_frames == 20
    assert any("10 of 30 frames have no time stamp" in n for n in ra.notes)


@pytest.mark.slow
def test_a_run_cut_by_sigkill_is_analysed_up_to_its_last_flush(tmp_path):
    path = tmp_path / "killed.h5"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(Path(__file__).with_name("killed_writer_proc.py")),
                             str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 60.0)
        assert ready and proc.stdout.readline().startswith("ready")
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=10)
    ra = analyse_run(path)
    assert ra.source.status == "running"
    assert "did not close" in ra.notes[0]
    assert ra.mechanics.passes and ra.mechanics.passes[0].cycles.n == 3
    index, _ = write_report(analyse_campaign([path]), tmp_path / "rep")
    assert "did not close" in index.read_text()


@pytest.mark.parametrize("content", [b"", b"not an hdf5 file at all\n" * 10])
def test_garbage_file_is_one_line_exit_2(tmp_path, capsys, content):
    p = tmp_path / "broken.h5"
    p.write_bytes(content)
    assert main(["analyse", str(p), "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "broken.h5" in err and "Traceback" not in err


@pytest.mark.slow
def test_truncated_hdf5_is_one_line_exit_2(saw, tmp_path, capsys):
    run, _ = saw
    p = write_measured_run(tmp_path / "whole.h5", run)
    cut = tmp_path / "cut.h5"
    data = p.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["analyse", str(cut), "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cut.h5" in err and "truncated" in err


@pytest.mark.slow
def test_a_folder_with_one_bad_file_reports_the_others(saw, tmp_path, capsys):
    run, _ = saw
    folder = tmp_path / "campaign"
    folder.mkdir()
    write_csv(folder / "good.csv", run)
    (folder / "bad.h5").write_bytes(b"garbage")
    assert main(["analyse", str(folder), "--out", str(tmp_path / "rep"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["runs"]) == 1
    assert any("bad.h5" in n for n in doc["notes"])


def test_missing_path_and_empty_folder(tmp_path, capsys):
    assert main(["analyse", str(tmp_path / "nope.h5")]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["analyse", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert "no such file" in err and "no *.csv or *.h5" in err
