"""The probes re-centred during a slide: the plan cuts the slide, the run moves the mounts, records
each move as an event, and D1 never leaves its range while the specimen slides; turned off with
``recentre_probes=0`` the same slide drives D1 over range."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from experiments.errors import PlanError
from experiments.protocols import PROTOCOLS
from experiments.recentre import RecentreProbes, ReturnProbeMounts
from experiments.runner import dry_run, get_protocol
from rigctl.config.loader import default_config
from rigctl.rigs import open_rig, rig_limits
from rigctl.storage.probe_events import RECENTRE_EVENT, parse_recentre
from rigctl.storage.reader import RunReader, read_run
from tests.experiments.test_runs import make_runner

LIMITS = rig_limits(default_config())
SLIDE = {"repetitions": "1", "travel_m": "100e-6", "velocity_m_s": "2e-5",
         "preload_hold_s": "0.5", "settle_s": "1", "recentre_probes": "1"}


@pytest.mark.parametrize("name", ["tlre", "force_sweep", "velocity_steps", "slide_hold_slide"])
def test_sliding_protocols_recentre_and_return_the_mounts(name: str) -> None:
    _, steps = dry_run(PROTOCOLS[name], {"recentre_probes": "1"}, LIMITS, 0.1)
    assert any(isinstance(s, RecentreProbes) for s in steps)
    assert any(isinstance(s, ReturnProbeMounts) for s in steps)
    _, off = dry_run(PROTOCOLS[name], {"recentre_probes": "0"}, LIMITS, 0.1)
    assert not any(isinstance(s, RecentreProbes | ReturnProbeMounts) for s in off)


def test_the_slide_is_cut_and_holds_keep_their_length() -> None:
    plan, _ = dry_run(get_protocol("tlre"), {"repetitions": "1", "recentre_probes": "1"}, LIMITS, 0.1)
    slides = [s for s in plan.steps if s.description.startswith("slide")]
    assert len(slides) == 9 and all("30.0 um" in s.description for s in slides)
    shs, _ = dry_run(get_protocol("slide_hold_slide"), {"recentre_probes": "1"}, LIMITS, 0.1)
    plain, _ = dry_run(get_protocol("slide_hold_slide"), {"recentre_probes": "0"}, LIMITS, 0.1)
    holds = [s.estimate_s for s in shs.steps if s.description.startswith("hold")]
    assert sum(holds) == pytest.approx(sum(s.estimate_s for s in plain.steps
                                          if s.description.startswith("hold")))


@pytest.mark.parametrize(("key", "bad"), [("recentre_every_m", "-1e-5"), ("recentre_every_m", "1e-9"),
                                          ("recentre_every_m", "nan"), ("recentre_probes", "0.5")])
def test_a_bad_setting_is_refused(key: str, bad: str) -> None:
    with pytest.raises(PlanError, match=key):
        dry_run(get_protocol("tlre"), {"recentre_probes": "1", key: bad}, LIMITS, 0.1)


def _slide_events(path: Path) -> tuple[list[tuple[float, str, str]], float]:
    with RunReader(path) as r:
        events = [(e.t_s, e.name, e.message) for e in r.events()]
    t_release = next(t for t, n, _ in events if n == "released")
    return events, t_release


def test_a_run_keeps_d1_in_range_while_sliding(tmp_path: Path) -> None:
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        on = tmp_path / "on.h5"
        outcome = make_runner(rig, "tlre", SLIDE, on).run()
        assert outcome.status == "completed", outcome.error
        off = tmp_path / "off.h5"
        outcome = make_runner(rig, "tlre", {**SLIDE, "recentre_probes": "0"}, off).run()
        assert outcome.status == "completed", outcome.error
        assert rig.sim.rig.probes[0].mount_m == pytest.approx(0.0, abs=1e-9)  # mounts returned

    events, t_release = _slide_events(off)
    assert any(n == "probe_over_range" and t < t_release for t, n, _ in events)

    events, t_release = _slide_events(on)
    assert not any(n == "probe_over_range" and t < t_release for t, n, _ in events)
    moves = [(t, parse_recentre(m)) for t, n, m in events if n == RECENTRE_EVENT]
    d1_moves = [(t, mv[1]) for t, mv in moves if mv is not None and mv[0] == "d1_m"]
    assert len(d1_moves) >= 4  # 100 um in 30 um pieces, and the mount's return
    run = read_run(on)
    for t, moved in d1_moves[:-1]:  # during the slide: the reading drops by the move, at rest
        # the event is marked just after the move (a paced rig may run up to 0.25 s ahead)
        near = np.flatnonzero((run.t_s > t - 0.45) & (run.t_s <= t + 0.02))
        k = near[int(np.argmax(np.abs(np.diff(run.d1_m[near]))))] + 1
        before = np.median(run.d1_m[k - 40:k])
        after = np.median(run.d1_m[k:k + 40])
        assert before - after == pytest.approx(moved, abs=0.2e-6), (t, run.t_s[k])
    assert sum(m for _, m in d1_moves) == pytest.approx(0.0, abs=1e-9)
