"""Protocols run on the simulated rig: results, pause/resume, abort, a dead device, a limit trip.

The rig is paced by the acquisition (``--speed max``), so these run many times faster than real time.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from experiments.context import Controls
from experiments.runner import Runner, get_protocol
from rigctl.config import adapters
from rigctl.config.loader import default_config
from rigctl.model import build_model
from rigctl.rigs import open_rig
from rigctl.storage.reader import RunReader, read_run

SHORT_TLRE = {"repetitions": "1", "travel_m": "160e-6", "velocity_m_s": "1e-5",
              "preload_hold_s": "1", "settle_s": "1"}


def make_runner(rig, protocol: str, params: dict, out: Path, **kw) -> Runner:
    return Runner(
        get_protocol(protocol), params, rig.devices, rig.limits, out=out,
        daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
        on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s), **kw,
    )


@pytest.fixture
def rig():
    with open_rig("sim", default_config(), speed=math.inf) as r:
        yield r


def start_and_wait_for_slide(runner: Runner, stage, slide_m: float) -> tuple[threading.Thread, list]:
    """Start ``runner`` in a thread; return once the tangential stage has slid ``slide_m`` (or 60 s)."""
    result: list = []
    th = threading.Thread(target=lambda: result.append(runner.run()))
    th.start()
    x0 = stage.position_m()
    deadline = time.monotonic() + 60
    while stage.position_m() < x0 + slide_m and time.monotonic() < deadline:
        time.sleep(0.005)
    return th, result


def status_of(path: Path) -> tuple[str, str, list[str]]:
    with h5py.File(path, "r", swmr=True) as f:
        return (f["entry/status"][()].decode(), f["entry/error"][()].decode(),
                [n.decode() for n in f["entry/events/name"][:]])


@pytest.mark.slow
def test_tlre_records_the_initial_stage_and_returns(rig, tmp_path):
    out = tmp_path / "tlre.h5"
    x0 = rig.devices.tangential_stage.position_m()
    outcome = make_runner(rig, "tlre", SHORT_TLRE, out).run()
    assert outcome.status == "completed", outcome.error
    run = read_run(out)
    # the initial stage reaches mu_s,max Fn (paper preset) at the set normal force
    assert run.ft_N.max() == pytest.approx(0.2 * 300.0, rel=0.05)
    sliding = run.x_stage_m > x0 + 5e-6
    assert np.median(run.fn_N[sliding]) == pytest.approx(300.0, abs=3.5)
    # the pre-load overshoot happened before the slide
    assert run.fn_N.max() == pytest.approx(360.0, abs=4.0)
    assert rig.devices.tangential_stage.position_m() == pytest.approx(x0, abs=1e-6)
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # load released
    status, _, events = status_of(out)
    assert status == "completed"
    protocol_events = [e for e in events if not e.startswith("probe_")]  # probe range: any time
    assert protocol_events[0] == "start" and protocol_events[-1] == "end"
    assert {"preload", "loaded", "released"} <= set(events)
    assert outcome.stats is not None and outcome.stats.daq_dropped == 0


@pytest.mark.slow
def test_the_record_reaches_the_end_of_the_protocol_when_the_reader_lags(rig, tmp_path):
    """The DAQ reader falls behind during the last step (a loaded machine; here each block is
    handed over 50 ms after it was read), so the paced rig runs up to the pacer's lag ahead of the
    recorded data when the protocol ends. The run still records up to the instant its last step
    ended: the return move is recorded finished (a CI run of the full suite recorded it 3.5 um
    short of the start)."""
    out = tmp_path / "lagging.h5"
    runner = make_runner(rig, "tlre", {**SHORT_TLRE, "travel_m": "60e-6"}, out)
    read = rig.devices.daq.read_block

    def read_late_in_the_return(*args, **kwargs):
        block = read(*args, **kwargs)
        if runner.ctx is not None and "return" in runner.ctx.current_step:
            time.sleep(0.05)  # the samples come out of the driver late (the stage moves on)
        return block

    rig.devices.daq.read_block = read_late_in_the_return
    outcome = runner.run()
    assert outcome.status == "completed", outcome.error
    with RunReader(out) as reader:
        t_end = next(e.t_s for e in reader.events() if e.name == "end")
    run = read_run(out)
    assert run.t_s[-1] >= t_end
    assert run.x_stage_m[-1] == pytest.approx(run.x_stage_m[0], abs=0.5e-6)


@pytest.mark.slow
def test_pause_stops_the_slide_and_resume_finishes_it(rig, tmp_path):
    out = tmp_path / "paused.h5"
    controls = Controls()
    runner = make_runner(rig, "tlre", SHORT_TLRE, out, controls=controls)
    stage = rig.devices.tangential_stage
    th, result = start_and_wait_for_slide(runner, stage, 30e-6)
    controls.pause()
    time.sleep(0.3)
    held = stage.position_m()
    t_rig = rig.sim.rig.t_s
    time.sleep(0.5)
    assert rig.sim.rig.t_s > t_rig + 1.0  # rig time goes on while paused...
    assert stage.position_m() == pytest.approx(held, abs=1e-9)  # ...and the slide does not
    controls.resume()
    th.join(timeout=120)
    assert result and result[0].status == "completed", result
    _, _, events = status_of(out)
    assert "pause" in events and "resume" in events


@pytest.mark.slow
def test_abort_brings_the_rig_to_a_safe_state(rig, tmp_path):
    out = tmp_path / "aborted.h5"
    controls = Controls()
    runner = make_runner(rig, "tlre", SHORT_TLRE, out, controls=controls)
    stage = rig.devices.tangential_stage
    th, result = start_and_wait_for_slide(runner, stage, 30e-6)
    controls.abort("operator pressed stop")
    th.join(timeout=60)
    outcome = result[0]
    assert outcome.status == "aborted" and "operator pressed stop" in outcome.error
    assert not stage.status().moving
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # normal load released
    status, error, events = status_of(out)
    assert status == "aborted" and "operator pressed stop" in error
    assert "safe_state" in events
    assert read_run(out).n_samples > 0


@pytest.mark.slow
def test_a_device_that_stops_answering_fails_the_run_safely(rig, tmp_path):
    out = tmp_path / "dead.h5"
    runner = make_runner(rig, "tlre", SHORT_TLRE, out)
    stage = rig.devices.tangential_stage
    th, result = start_and_wait_for_slide(runner, stage, 20e-6)
    rig.sim.faults["daq"].silent = True
    t_fault = time.monotonic()
    t_stopped: list[float] = []
    while th.is_alive() and not t_stopped:
        if not stage.status().moving:
            t_stopped.append(time.monotonic())
        time.sleep(0.005)
    th.join(timeout=60)
    outcome = result[0]
    assert outcome.status == "failed"
    assert "daq" in outcome.error and "DeviceTimeout" in outcome.error
    assert t_stopped and t_stopped[0] - t_fault < 1.0, t_stopped  # stopped within 1 s of the fault
    # safe state reached quickly: the tangential stage stopped, the normal stage retracted
    assert not stage.status().moving
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)
    assert time.monotonic() - t_fault < 10.0
    status, error, _ = status_of(out)
    assert status == "failed" and "daq" in error
    assert read_run(out).n_samples > 10_000  # the data before the fault is kept


def test_a_force_limit_violated_mid_protocol_fails_and_releases(tmp_path):
    """Normal coupling (kappa 0.5) raises Fn with Ft: a 315 N limit trips during the slide, though the
    plan itself (300 N, no pre-load) was within it."""
    model = build_model("paper", effects=["normal_coupling"],
                        effect_params={"normal_coupling": {"kappa": 0.5}})
    out = tmp_path / "limit.h5"
    with open_rig("sim", default_config(), speed=math.inf, model=model) as rig:
        params = {**SHORT_TLRE, "preload_factor": "1.0"}
        outcome = make_runner(rig, "tlre", params, out, force_limit_N=315.0).run()
        assert outcome.status == "failed"
        assert "ForceLimitError" in outcome.error and "315" in outcome.error
        assert not rig.devices.tangential_stage.status().moving
        assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # retracted after the trip
    run = read_run(out)
    assert 312.0 < run.fn_N.max() < 330.0  # tripped at the crossing, not far beyond
    assert status_of(out)[0] == "failed"


@pytest.mark.slow
def test_a_stage_that_stops_answering_fails_the_run_and_the_load_is_released(rig, tmp_path):
    """The tangential stage's controller goes silent mid-slide: the run fails naming it, the normal
    load (the one thing still reachable) is released, the data before the fault is kept."""
    out = tmp_path / "dead_stage.h5"
    runner = make_runner(rig, "tlre", SHORT_TLRE, out)
    stage = rig.devices.tangential_stage
    th, result = start_and_wait_for_slide(runner, stage, 20e-6)
    rig.sim.faults["tangential_stage"].silent = True
    t_fault = time.monotonic()
    th.join(timeout=60)
    outcome = result[0]
    assert outcome.status == "failed"
    assert "tangential did not answer" in outcome.error  # the stage is named
    assert "safe state incomplete" in outcome.error  # its stop could not be sent: said, not hidden
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # released
    assert time.monotonic() - t_fault < 15.0
    status, error, events = status_of(out)
    assert status == "failed" and "tangential did not answer" in error
    assert "safe_state" in events
    run = read_run(out, validate=False)
    assert run.n_samples > 10_000
    # forces went on being recorded through the release (the DAQ thread does not die with the
    # stage): the file ends with the load released, the dead stage's position missing (NaN)
    assert abs(float(np.mean(run.fn_N[-50:]))) < 5.0, run.fn_N[-50:]
    assert np.isnan(run.x_stage_m[-1])
    assert np.isfinite(run.x_stage_m[0])


@pytest.mark.slow
def test_a_release_that_does_not_happen_is_reported_from_the_measured_force(rig, tmp_path):
    """The normal stage acknowledges the retraction but does not move (a jammed or disabled motor):
    the safe state is judged on the measured Fn, so the run says the load is still on."""
    out = tmp_path / "jammed.h5"
    controls = Controls()
    runner = make_runner(rig, "tlre", SHORT_TLRE, out, controls=controls)
    stage = rig.devices.tangential_stage
    th, result = start_and_wait_for_slide(runner, stage, 20e-6)
    rig.devices.normal_stage.move_absolute = lambda *a, **k: None  # acknowledged, never executed
    controls.abort("test: abort with a jammed normal stage")
    th.join(timeout=60)
    outcome = result[0]
    assert outcome.status == "aborted"
    assert "the normal load is still on" in outcome.error
    assert rig.sim.rig.state.fn_N > 250.0  # indeed still loaded: the report is true
    _, error, _ = status_of(out)
    assert "the normal load is still on" in error


def test_a_frozen_force_reading_stops_the_load_and_names_the_daq(tmp_path):
    """The DAQ freezes 1 s into a TLRE, before contact, with a 500 N force limit (docs/reliability.md):
    the reading stays at ~0 N, so the contact search alone would drive the normal stage on to the
    rig's mechanical over-load. The stale-reading watchdog stops the stages within its window of
    device time and the run fails naming the DAQ; the load is released."""
    out = tmp_path / "frozen.h5"
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        runner = make_runner(rig, "tlre", SHORT_TLRE, out, force_limit_N=500.0)
        th = threading.Thread(target=lambda: result.append(runner.run()))
        result: list = []
        th.start()
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not (runner.ctx and runner.ctx.acq.t_s >= 1.0):
            time.sleep(0.001)
        rig.sim.faults["daq"].stuck = True
        th.join(timeout=60)
        outcome = result[0]
        assert outcome.status == "failed"
        assert "frozen" in outcome.error and "daq" in outcome.error, outcome.error
        assert "StageAlarm" not in outcome.error and "over-load" not in outcome.error
        # never pressed towards the rig's over-load: at most a few newtons when the stage stopped
        assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)
        assert not rig.devices.normal_stage.status().fault
    status, error, events = status_of(out)
    assert status == "failed" and "frozen" in error
    assert "safe_state" in events


def test_a_reading_frozen_mid_load_is_not_reported_as_a_load_still_on(tmp_path):
    """Frozen at a few tens of newtons while loading: the run fails naming the frozen DAQ, and the
    safe-state check does not claim from the frozen value that the load is still on."""
    out = tmp_path / "frozen_mid.h5"
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        runner = make_runner(rig, "tlre", SHORT_TLRE, out)
        result: list = []
        th = threading.Thread(target=lambda: result.append(runner.run()))
        th.start()
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and rig.sim.rig.state.fn_N < 40.0:
            time.sleep(0.0005)
        rig.sim.faults["daq"].stuck = True
        th.join(timeout=60)
        outcome = result[0]
        assert outcome.status == "failed" and "frozen" in outcome.error, outcome.error
        assert "still on" not in outcome.error
        assert "could not be confirmed" in outcome.error
        assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)  # released in fact


@pytest.mark.slow
def test_a_failure_caused_by_an_abort_ends_the_run_aborted(rig, tmp_path):
    """An e-stop stops the stages and aborts the run; the stage alarm it causes can reach the step
    (as a device error of the acquisition) before the abort flag does. The run was still aborted
    by the operator: its status says so and its error keeps what failed."""
    out = tmp_path / "estopped.h5"
    controls = Controls()
    raised: list[str] = []

    def with_alarm_after_abort(acq):
        rig.pacer.follow(lambda: acq.t_s)
        check = acq.check

        def check_then_alarm() -> None:
            check()
            if controls.aborted and not raised:
                raised.append("alarm")
                raise RuntimeError("tangential stage alarm 5 (emergency stop)")
        acq.check = check_then_alarm

    runner = Runner(get_protocol("tlre"), SHORT_TLRE, rig.devices, rig.limits, out=out,
                    daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
                    on_acquisition=with_alarm_after_abort, controls=controls)
    th, result = start_and_wait_for_slide(runner, rig.devices.tangential_stage, 20e-6)
    controls.abort("emergency stop by the operator")
    th.join(timeout=60)
    outcome = result[0]
    assert raised, "the injected alarm was never raised"
    assert outcome.status == "aborted", outcome.error
    assert "emergency stop by the operator" in outcome.error and "alarm 5" in outcome.error
    assert rig.sim.rig.state.fn_N == pytest.approx(0.0, abs=0.05)
    status, error, events = status_of(out)
    assert status == "aborted" and "alarm 5" in error and "safe_state" in events


def _run_blind(config_text: str, out: Path, go_blind) -> tuple[object, float, float, bool, float]:
    """A short TLRE with the force sensor going blind when ``go_blind(rig)`` says; returns the
    outcome, the highest true normal force and normal-stage position seen, whether the stage's
    over-load alarm was raised, and the true normal force at the end."""
    from rigctl.config.loader import parse_config
    from rigctl.rigs import rig_limits

    config = parse_config(config_text)
    with open_rig("sim", config, speed=math.inf) as rig:
        runner = Runner(get_protocol("tlre"), SHORT_TLRE, rig.devices, rig_limits(config), out=out,
                        daq_layout=adapters.daq_layout(rig.config), camera_layout=None,
                        on_acquisition=lambda acq: rig.pacer.follow(lambda: acq.t_s))
        result: list = []
        th = threading.Thread(target=lambda: result.append(runner.run()))
        th.start()
        fn_max = z_max = 0.0
        alarm = False
        while th.is_alive():
            if not rig.sim.faults["daq"].blind and go_blind(rig):
                rig.sim.faults["daq"].blind = True
            fn_max = max(fn_max, rig.sim.rig.state.fn_N)
            z_max = max(z_max, rig.devices.normal_stage.position_m())
            alarm = alarm or rig.devices.normal_stage.status().alarm_code == 3
            time.sleep(0.001)
        th.join(timeout=60)
        fn_end = rig.sim.rig.state.fn_N
    return result[0], fn_max, z_max, alarm, fn_end


def test_a_blind_force_sensor_before_contact_stops_the_search_at_its_configured_end(tmp_path):
    """The force channels read no load from the start (a broken bridge: live noise, so the
    stale-reading watchdog does not trip): the contact search stops at contact_search_end_m instead
    of driving the normal stage into the specimen up to the rig's over-load."""
    outcome, fn_max, z_max, alarm, fn_end = _run_blind("", tmp_path / "blind.h5", lambda rig: True)
    assert outcome.status == "failed"
    assert "contact_search_end_m" in outcome.error and "blind" in outcome.error, outcome.error
    assert z_max <= 0.02005 + 1e-9
    assert not alarm and fn_max < 800.0, fn_max
    assert fn_end == pytest.approx(0.0, abs=0.05)  # the safe state released the load


@pytest.mark.slow
def test_a_force_sensor_blind_under_load_stops_within_the_approach_bound(tmp_path):
    """The sensor goes blind half-way up the load (true Fn 100 N): the load step keeps pressing on a
    reading of ~0 N until the stage would pass max_approach_m beyond the first contact reading, and
    stops there, below the rig's over-load (a 500 N force limit with its 80 um deflection)."""
    text = "[normal_stage.limits]\nmax_force_N = 500\nmax_approach_m = 85e-6\n"
    outcome, fn_max, _, alarm, fn_end = _run_blind(text, tmp_path / "blind_loaded.h5",
                                           lambda rig: rig.sim.rig.state.fn_N > 100.0)
    assert outcome.status == "failed"
    assert "max_approach_m" in outcome.error and "blind" in outcome.error, outcome.error
    assert not alarm and fn_max < 800.0, fn_max
    assert fn_max > 100.0  # it did go blind under load
    assert fn_end == pytest.approx(0.0, abs=0.05)  # the safe state released the load

