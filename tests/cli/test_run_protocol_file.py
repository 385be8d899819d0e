"""`rigctl run path/to/protocol.py`: a protocol file through the command line, on the simulated rig.

The worked example (docs/examples/load_steps.py) is dry-run against the rig's limits like a
built-in protocol, recorded to a run file that says where its protocol came from, and the errors of
an unusable file are one line with exit code 2.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from rigctl.storage.reader import RunReader
from tests.cli.test_run_cli import rigctl

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "load_steps.py"
QUICK = ["--param", "slide_m=60e-6", "--param", "settle_s=1", "--param", "preload_hold_s=1"]


@pytest.mark.slow
def test_the_dry_run_refuses_a_file_protocol_the_same_way_as_a_built_in(tmp_path):
    out = tmp_path / "never.h5"
    mine = rigctl("run", str(EXAMPLE), "--param", "forces_N=300", "--param", "slide_m=0.25",
                  "--param", "velocity_m_s=1.3e-6", "--speed", "max", "--out", str(out))
    tlre = rigctl("run", "tlre", "--param", "travel_m=0.25", "--speed", "max", "--out", str(out))
    assert mine.returncode == tlre.returncode == 2
    assert mine.stderr == tlre.stderr
    assert mine.stderr.startswith("rigctl: error: dry run refused: step 'slide 250000.0 um")
    assert "above the maximum 0.2 m" in mine.stderr and mine.stderr.count("\n") == 1
    assert not out.exists()


@pytest.mark.slow
def test_a_file_protocol_runs_on_the_simulated_rig_and_is_recorded(tmp_path):
    out = tmp_path / "steps.h5"
    r = rigctl("run", "--protocol-file", str(EXAMPLE), "--speed", "max", "--no-camera",
               "--out", str(out), *QUICK)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("protocol load_steps: 11 steps")
    assert f"completed: {out}" in r.stdout
    with RunReader(out) as run:
        assert run.status == "completed" and run.protocol == "load_steps"
        assert run.parameters["forces_N"] == [200.0, 300.0, 400.0]
        assert run.parameters["slide_m"] == pytest.approx(60e-6)
        meta = run.metadata
        d = run.read_daq()
        events = run.events()
    assert meta["protocol_file"] == str(EXAMPLE)
    assert meta["protocol_file_sha256"] == hashlib.sha256(EXAMPLE.read_bytes()).hexdigest()
    # each slide at its own force: the step markers bound the slides, Fn holds the set force
    marks = {e.name: e.t_s for e in events}
    t, fn, x = d["t_s"], d["fn_N"], d["x_stage_m"]
    # the stage's position is polled once per DAQ block and drawn as the line between polls, so
    # near a move it leans up to a poll interval early or late: a slide's travel is read from the
    # median positions over the normal-load steps before its settle and after it, where the
    # tangential stage stands still for seconds
    def still_m(step: int) -> float:
        w = (t > marks[f"step {step}"]) & (t < marks[f"step {step + 1}"])
        return float(np.median(x[w]))

    for k, force in ((3, 200.0), (6, 300.0), (9, 400.0)):
        during = (t > marks[f"step {k}"]) & (t < marks[f"step {k + 1}"])
        assert np.median(fn[during]) == pytest.approx(force, abs=5.0)
        assert still_m(k + 1) - still_m(k - 2) == pytest.approx(60e-6, abs=0.5e-6)
    assert abs(fn[-1]) < 1.0 and x[-1] == pytest.approx(x[0], abs=1e-6)  # released, returned


@pytest.mark.parametrize(("make", "message"), [
    (lambda d: d / "missing.py", "missing.py: no such file"),
    (lambda d: _file(d, "x = 1\n"), "defines no Protocol"),
    (lambda d: _file(d, "x = 1\ndef f(:\n"), "bad.py, line 2: syntax error"),
])
@pytest.mark.slow
def test_an_unusable_protocol_file_is_one_line_and_exit_2(tmp_path, make, message):
    r = rigctl("run", str(make(tmp_path)), "--dry-run")
    assert r.returncode == 2
    assert r.stderr.startswith("rigctl: error: protocol file ") and message in r.stderr
    assert r.stderr.count("\n") == 1


@pytest.mark.slow
def test_a_name_and_a_protocol_file_together_are_refused():
    r = rigctl("run", "tlre", "--protocol-file", str(EXAMPLE), "--dry-run")
    assert r.returncode == 2 and "not both" in r.stderr


def _file(folder: Path, text: str) -> Path:
    path = folder / "bad.py"
    path.write_text(text)
    return path
