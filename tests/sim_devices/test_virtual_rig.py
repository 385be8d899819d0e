"""The one virtual rig: engine, stages and contact law on one clock, read by every device."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from sim_devices.sample_ring import SamplesLostError
from sim_devices.stage_axis import Alarm
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig


def loaded_rig(fn_N: float, **kwargs: object) -> VirtualRig:
    rig = VirtualRig(**kwargs)  # type: ignore[arg-type]
    rig.normal.enable()
    rig.tangential.enable()
    rig.normal.move_to(rig.config.contact.z_for_fn_m(fn_N), 2e-3)
    rig.advance_to(1.0)
    return rig


def test_normal_stage_position_gives_fn_through_the_contact_law() -> None:
    rig = VirtualRig()
    assert rig.state.fn_N == 0.0  # the normal stage starts short of the contact
    rig.normal.enable()
    z_target = rig.config.contact.z_for_fn_m(250.0)
    rig.normal.move_to(z_target, 1e-3)
    rig.advance_to(1.0)
    s = rig.samples(0, rig.k + 1)
    expected = np.array([rig.config.contact.fn_N(z) for z in s.z_normal_m])
    np.testing.assert_allclose(s.fn_N, expected, rtol=1e-9, atol=1e-9)
    assert rig.state.fn_N == pytest.approx(250.0, rel=1e-9)
    assert np.all(np.diff(s.fn_N) >= -1e-9)  # approaching: never decreasing


def test_stick_slip_on_the_sample_grid() -> None:
    rig = loaded_rig(300.0)
    rig.tangential.move_to(rig.state.x_stage_m + 0.3e-3, 1e-5)
    rig.advance_to(25.0)
    s = rig.samples(0, rig.k + 1)
    np.testing.assert_array_equal(s.t_s, np.arange(rig.k + 1) / rig.rate_hz)
    assert np.all(np.isfinite(s.ft_N))
    peak = float(s.ft_N.max())
    assert peak == pytest.approx(0.2 * 300.0, rel=0.02)  # mu_s,max * Fn (seed, Sec. 5.3)
    drops = -np.diff(s.ft_N)
    assert np.count_nonzero(drops > 5.0) >= 3  # the peak's drop and stable-stage slips
    assert rig.state.stage == 1 and rig.state.n_slips >= 3


def test_overload_latches_alarm_3_and_fn_never_exceeds_the_maximum() -> None:
    rig = VirtualRig(config=VirtualRigConfig(max_load_N=400.0))
    rig.normal.enable()
    rig.normal.move_to(rig.config.contact.z_for_fn_m(300.0) + 1e-3, 1e-4)
    rig.advance_to(12.0)
    st = rig.state.normal
    assert st.alarm == Alarm.OVERLOAD and st.fault and not st.moving
    s = rig.samples(0, rig.k + 1)
    assert s.fn_N.max() <= 400.0 + 1e-9
    assert s.fn_N.max() > 399.0


def test_clock_real_time_and_accelerated() -> None:
    for speed in (1.0, 10.0):
        t0 = time.monotonic()
        with VirtualRig(speed=speed) as rig:
            t1 = time.monotonic()
            time.sleep(0.3)
            now = rig.clock.now_s()
            t2 = time.monotonic()
            assert rig.wait_until(now, 2.0)  # the engine keeps up with its clock
        assert (t2 - t1) * speed <= now <= (t2 - t0) * speed  # the clock starts at construction


def test_old_samples_are_reported_lost_not_invented() -> None:
    rig = VirtualRig(config=VirtualRigConfig(history_s=1.0))
    rig.advance_to(3.0)
    with pytest.raises(SamplesLostError) as err:
        rig.samples(0, 10)
    assert err.value.first_available == rig.k + 1 - 1024
    assert len(rig.samples(rig.k - 9, rig.k + 1)) == 10


def test_commands_from_threads_while_the_clock_runs() -> None:
    errors: list[BaseException] = []
    with VirtualRig(speed=20.0) as rig:
        rig.tangential.enable()

        def jog() -> None:
            try:
                for i in range(20):
                    rig.tangential.move_to(0.1 + (i % 2) * 1e-4, 5e-3)
                    _ = rig.state.tangential.position_m
                    time.sleep(0.005)
            except BaseException as exc:
                errors.append(exc)

        threads = [threading.Thread(target=jog) for _ in range(3)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        rig.check()
        s = rig.samples(0, rig.k + 1)
    assert not errors
    np.testing.assert_allclose(np.diff(s.t_s), 1.0 / 1024.0)
    assert np.all(np.isfinite(s.ft_N))


def test_manual_rig_refuses_non_finite_time() -> None:
    rig = VirtualRig()
    with pytest.raises(ValueError):
        rig.advance_to(float("nan"))
    rig.advance_to(0.5)
    rig.advance_to(0.2)  # never backwards: a no-op
    assert rig.t_s == pytest.approx(0.5)
