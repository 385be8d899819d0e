"""The probes re-centred while the stage slides: the plan keeps each slide one piece (the drive is
never stopped), the run moves the mounts mid-slide, records each move with its window, D1 never
leaves its range while the specimen slides, the stitched delta is continuous across every move, and
the analysis finds one pass per repetition; turned off with ``recentre_probes=0`` the same slide
drives D1 over range."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from experiments.errors import PlanError
from experiments.protocols import PROTOCOLS
from experiments.recentre import MOUNT_SETTLE_S, RecentredSlide, ReturnProbeMounts
from experiments.runner import dry_run, get_protocol
from experiments.steps import MoveTangential, Step
from rigctl.analysis.pipeline import analyse_run
from rigctl.analysis.source import open_source
from rigctl.config.loader import default_config
from rigctl.rigs import open_rig, rig_limits
from rigctl.storage.probe_events import RECENTRE_EVENT, MountMove, parse_recentre
from rigctl.storage.reader import RunReader
from sim_devices.sensors import ProbeSpec
from tests.experiments.test_runs import make_runner

LIMITS = rig_limits(default_config())
SLIDE = {"repetitions": "2", "travel_m": "100e-6", "velocity_m_s": "2e-5",
         "preload_hold_s": "0.5", "settle_s": "1"}
SLIDING = ["tlre", "force_sweep", "velocity_steps", "slide_hold_slide"]


@pytest.mark.parametrize("name", SLIDING)
def test_sliding_protocols_recentre_by_default_and_return_the_mounts(name: str) -> None:
    _, steps = dry_run(PROTOCOLS[name], {}, LIMITS, 0.1)
    assert any(isinstance(s, RecentredSlide) for s in steps)
    assert any(isinstance(s, ReturnProbeMounts) for s in steps)
    _, off = dry_run(PROTOCOLS[name], {"recentre_probes": "0"}, LIMITS, 0.1)
    assert not any(isinstance(s, RecentredSlide | ReturnProbeMounts) for s in off)


@pytest.mark.parametrize("name", SLIDING)
def test_the_drive_is_planned_as_without_recentring(name: str) -> None:
    """Same slides (one piece each, same distance and speed), same holds, same duration."""
    on, steps = dry_run(PROTOCOLS[name], {}, LIMITS, 0.1)
    off, plain = dry_run(PROTOCOLS[name], {"recentre_probes": "0"}, LIMITS, 0.1)

    def drive(ss: list[Step]) -> list[tuple[str, float, float]]:
        return [(s.name, getattr(s, "distance_m", 0.0), getattr(s, "velocity_m_s", 0.0))
                for s in ss if not isinstance(s, ReturnProbeMounts)]

    assert drive(steps) == drive(plain)
    assert all(type(s) is not MoveTangential for s in steps)
    assert on.duration_s == pytest.approx(off.duration_s)


@pytest.mark.parametrize(("key", "bad"), [("recentre_headroom_m", "-1e-5"),
                                          ("recentre_headroom_m", "1e-9"),
                                          ("recentre_headroom_m", "nan"),
                                          ("recentre_probes", "0.5")])
def test_a_bad_setting_is_refused(key: str, bad: str) -> None:
    with pytest.raises(PlanError, match=key):
        dry_run(get_protocol("tlre"), {key: bad}, LIMITS, 0.1)


def _events(path: Path) -> tuple[list[tuple[float, str, str]], list[tuple[float, float]]]:
    """The events, and the (start, release) times of each slide."""
    with RunReader(path) as r:
        events = [(e.t_s, e.name, e.message) for e in r.events()]
    starts = [t for t, n, m in events if n.startswith("step") and m.startswith("slide")]
    ends = [t for t, n, m in events if n.startswith("step") and m.startswith("release")]
    return events, list(zip(starts, ends, strict=True))


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A short TLRE of two repetitions re-centred (the default), and one repetition not."""
    folder = tmp_path_factory.mktemp("recentre")
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        on = folder / "on.h5"
        outcome = make_runner(rig, "tlre", SLIDE, on).run()
        assert outcome.status == "completed", outcome.error
        assert rig.sim.rig.probes[0].mount_m == pytest.approx(0.0, abs=1e-9)  # mounts returned
        off = folder / "off.h5"
        plain = {**SLIDE, "repetitions": "1", "recentre_probes": "0"}
        outcome = make_runner(rig, "tlre", plain, off).run()
        assert outcome.status == "completed", outcome.error
    return on, off


@pytest.mark.slow
def test_without_recentring_d1_goes_over_range_while_sliding(runs: tuple[Path, Path]) -> None:
    events, slides = _events(runs[1])
    assert any(n == "probe_over_range" and a < t < b for t, n, _ in events for a, b in slides)


def test_d1_stays_in_range_and_the_mounts_move_mid_slide(runs: tuple[Path, Path]) -> None:
    events, slides = _events(runs[0])
    assert not any(n == "probe_over_range" and a < t < b for t, n, _ in events for a, b in slides)
    moves = [m for _, n, msg in events if n == RECENTRE_EVENT
             for m in [parse_recentre(msg)] if m is not None and m.column == "d1_m"]
    speed_m_s = ProbeSpec().mount_speed_m_s
    # each window covers the mount's travel and settling (to the message's 0.1 ms); beyond that it
    # holds the command's round trip in device time, which at speed=inf grows with the host's load
    assert all(m.has_window and m.duration_s >= abs(m.moved_m) / speed_m_s + MOUNT_SETTLE_S - 1e-4
               for m in moves)
    for a, b in slides:  # a move while the stage goes on, away from its ends, done before release
        mid = [m for m in moves if a + 1.0 < m.t_start_s < b - 1.0]
        assert len(mid) >= 1
        assert all(m.t_start_s + m.duration_s < b for m in mid)
    assert sum(m.moved_m for m in moves) == pytest.approx(0.0, abs=1e-9)


def test_the_drive_is_never_stopped(runs: tuple[Path, Path]) -> None:
    """The stage's velocity is continuous through every slide: no stop at the re-centrings."""
    _, slides = _events(runs[0])
    run = open_source(runs[0]).run
    for a, b in slides:
        go, stop = _travelling(run.t_s, run.x_stage_m, a, b)
        m = (run.t_s > go + 0.5) & (run.t_s < stop - 0.5)
        t, x = run.t_s[m], run.x_stage_m[m]
        k = np.searchsorted(t, np.arange(t[0], t[-1] - 0.25, 0.25))
        v = np.diff(x[k]) / np.diff(t[k])  # over 0.25 s: a 1 s stop would show as v = 0
        assert np.all(v > 0.5 * 2e-5), (a, float(np.min(v)))


def _travelling(t_s: np.ndarray, x_m: np.ndarray, a: float, b: float) -> tuple[float, float]:
    """When the stage left its start and reached its end within the slide's steps [a, b], from
    its recorded position (the step events bracket the motion with the runner's own latency: the
    stage may stop half a second before the next step is recorded)."""
    m = (t_s >= a) & (t_s <= b)
    t, x = t_s[m], x_m[m]
    tol = 0.01 * abs(float(x[-1] - x[0]))  # 1 % of the travel: above the position's resolution
    between = (np.abs(x - x[0]) > tol) & (np.abs(x - x[-1]) > tol)
    return float(t[between][0]), float(t[between][-1])


def _window_edges(run_t: np.ndarray, move: MountMove) -> tuple[int, int]:
    a = int(np.searchsorted(run_t, move.t_start_s, side="right"))
    b = int(np.searchsorted(run_t, move.t_start_s + move.duration_s, side="right"))
    return a - 1, b


def test_the_stitched_delta_is_continuous_across_each_move(runs: tuple[Path, Path]) -> None:
    src = open_source(runs[0])
    run = src.run
    moves = [m for e in src.markers if e.name == RECENTRE_EVENT
             for m in [parse_recentre(e.message)] if m is not None]
    _, slides = _events(runs[0])
    inside = [m for m in moves if any(a - 0.1 < m.t_start_s < b for a, b in slides)]
    assert len(inside) >= 4  # at each slide's start (D1 and D2), and D1 in the middle
    for m in inside:
        i, j = _window_edges(run.t_s, m)
        jump = getattr(run, m.column)[j] - getattr(run, m.column)[i]
        # at most what the stage (20 um/s) drives over the window; the move itself is ~27 um
        assert abs(jump) < 2e-5 * m.duration_s + 1e-6, (m, jump)
    d1 = run.d1_m[(run.t_s > slides[0][0]) & (run.t_s < slides[0][1])]
    assert np.ptp(d1) > 50e-6  # stitched: the slide's ~60 um, not the re-centred readings' ~35 um


@pytest.mark.slow
def test_the_analysis_finds_one_pass_per_repetition(runs: tuple[Path, Path]) -> None:
    analysis = analyse_run(runs[0])
    passes = analysis.mechanics.passes
    assert len(passes) == 2
    windows = [m for e in open_source(runs[0]).markers if e.name == RECENTRE_EVENT
               for m in [parse_recentre(e.message)] if m is not None and m.has_window]
    for rec in passes:
        a, b = rec.pas.t_motion_s, rec.pas.t_end_s
        m = (rec.run.t_s > a) & (rec.run.t_s < b)
        # only the mounts' moves are left out: valid but for the recorded windows (and a sample
        # at each window's edges)
        moving = sum(max(0.0, min(w.t_start_s + w.duration_s, b) - max(w.t_start_s, a))
                     for w in windows)
        assert rec.delta_valid[m].mean() > 1.0 - moving / (b - a) - 0.01


@pytest.mark.slow
def test_every_stick_phase_of_the_default_tlre_has_delta_in_range(tmp_path: Path) -> None:
    """One repetition of the default TLRE (270 um at 1.3 um/s, ~210 s of rig time): every stick
    phase of the stable stage is measured (delta valid from its start to its peak, but for the
    mounts' short moves)."""
    out = tmp_path / "tlre.h5"
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        outcome = make_runner(rig, "tlre", {"repetitions": "1"}, out).run()
        assert outcome.status == "completed", outcome.error
    (rec,) = analyse_run(out).mechanics.passes
    stable = np.flatnonzero(rec.stable)
    assert stable.size >= 3
    for j in stable:
        a, b = np.searchsorted(rec.run.t_s, (rec.cycles.t_start_s[j], rec.cycles.t_peak_s[j]))
        assert rec.delta_valid[a:b].mean() > 0.98, j
