"""The terminal progress of `rigctl run` (rigctl/cli/progress.py): from the rig clock, held while
paused, never past 100 %, warnings and pause/resume on their own lines."""

from __future__ import annotations

import io
import logging

from rigctl.cli.progress import RunProgress, warnings_on_their_own_lines


class Clock:
    t_s = 0.0


def _bar(paused: list[bool]) -> tuple[RunProgress, Clock, io.StringIO]:
    out = io.StringIO()
    clock = Clock()
    bar = RunProgress([10.0, 20.0, 30.0], 10.0, lambda: paused[0], stream=out)
    bar._clock = lambda: clock.t_s  # attach() without its redraw thread
    return bar, clock, out


def test_the_bar_follows_the_rig_clock_within_a_step() -> None:
    bar, clock, out = _bar([False])
    bar.on_step(1, 3, "load", 0.0, 60.0)
    clock.t_s = 4.0
    bar.tick()
    assert bar.bar.n == 4.0  # moves inside a step, not only at step starts
    clock.t_s = 25.0  # the step overruns its estimate: the bar holds at its end
    bar.tick()
    assert bar.bar.n == 10.0
    bar.on_step(2, 3, "slide", 25.0, 50.0)
    clock.t_s = 30.0
    bar.tick()
    assert bar.bar.n == 15.0
    assert "ETA 45 s, ~4 s wall" in out.getvalue().split("\r")[-1]
    bar.close()


def test_time_while_paused_does_not_count_and_is_said() -> None:
    paused = [False]
    bar, clock, out = _bar(paused)
    bar.on_step(2, 3, "slide", 10.0, 50.0)  # step 2 starts at rig time 0 in this test
    clock.t_s = 5.0
    bar.tick()
    paused[0] = True
    bar.tick()
    for t in (8.0, 12.0, 30.0):
        clock.t_s = t
        bar.tick()
        assert bar.bar.n == 15.0  # 10 s of step 1 + the 5 s before the pause
    paused[0] = False
    bar.tick()
    clock.t_s = 32.0
    bar.tick()
    assert bar.bar.n == 17.0
    text = out.getvalue()
    assert "\npaused" in text or text.startswith("paused") or "\rpaused" in text
    assert "resumed\n" in text and "PAUSED" in text
    bar.close()


def test_warnings_go_on_their_own_lines(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A log warning while the bar is shown goes through tqdm.write: the bar is cleared, the
    warning printed on its own line, the bar redrawn below it."""
    import rigctl.cli.progress as progress

    written: list[str] = []
    monkeypatch.setattr(progress.tqdm, "write", lambda s, *a, **k: written.append(s))
    with warnings_on_their_own_lines():
        logging.getLogger("rigctl.test").warning("probe over range")
        logging.getLogger("rigctl.test").info("not shown")
    logging.getLogger("rigctl.test").warning("after: not through the bar")
    assert written == ["WARNING: probe over range"]
