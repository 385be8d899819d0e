"""Ctrl-C and SIGTERM during a search are raised where the search waits and never lost
(rigctl/workbench/interrupts.py): a signal whose exception Python drops in a destructor is raised
again at the next check, or at the block's end."""

from __future__ import annotations

import gc
import os
import signal
import sys
import time

import pytest

from rigctl.workbench.budget import Budget
from rigctl.workbench.interrupts import Terminated, raise_if_signalled, signals_raise


@pytest.fixture(autouse=True)
def _default_handlers():
    """Each test starts from SIGINT and SIGTERM at their defaults, as a command does (a test run
    earlier in the same process may have left its own handlers: `rigctl run`'s, say), and leaves
    them as it found them."""
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    yield
    for s, handler in before.items():
        signal.signal(s, handler)


class _SignalsInItsDestructor:
    """An object whose destructor receives ``signum``: the handler runs inside ``__del__``, where
    Python prints the exception ("Exception ignored in ...") and drops it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        os.kill(os.getpid(), self.signum)
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:  # the handler runs at one of these bytecodes
            pass


def _drop_a_signal(signum: int) -> None:
    obj = _SignalsInItsDestructor(signum)
    del obj
    gc.collect()


@pytest.mark.parametrize(("signum", "kind"), [(signal.SIGINT, KeyboardInterrupt),
                                              (signal.SIGTERM, Terminated)])
def test_a_signal_dropped_in_a_destructor_is_raised_at_the_next_check(signum, kind):
    with pytest.raises(kind), signals_raise():
        _drop_a_signal(signum)  # the exception was printed and dropped: we are still here
        raise_if_signalled()
        pytest.fail("the noted signal was not raised")


def test_the_budget_s_check_raises_a_dropped_ctrl_c():
    budget = Budget(max_evaluations=10)
    with pytest.raises(KeyboardInterrupt), signals_raise():
        _drop_a_signal(signal.SIGINT)
        budget.check()
        pytest.fail("the budget's check did not raise the noted Ctrl-C")


def test_a_block_that_ends_with_a_dropped_signal_raises_it_at_its_end():
    with pytest.raises(Terminated) as exc, signals_raise():
        _drop_a_signal(signal.SIGTERM)
    assert exc.value.exit_code == 143


def test_a_signal_raises_at_once_and_the_defaults_come_back():
    with pytest.raises(KeyboardInterrupt), signals_raise():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1.0)  # interrupted at once (the bound only matters if it is not)
        pytest.fail("SIGINT did not raise")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    raise_if_signalled()  # nothing noted outside the block


def test_nested_blocks_are_one_and_nothing_is_left_noted():
    with pytest.raises(KeyboardInterrupt), signals_raise():
        with signals_raise():
            _drop_a_signal(signal.SIGINT)
        pytest.fail("the inner block's end must not swallow the noted signal")  # pragma: no cover
    with signals_raise():  # a fresh block starts with nothing noted
        raise_if_signalled()


def test_a_handler_someone_installed_is_left_alone():
    seen: list[int] = []

    def own(signum, frame):
        seen.append(signum)

    previous = signal.signal(signal.SIGINT, own)
    try:
        with signals_raise():
            assert signal.getsignal(signal.SIGINT) is own
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            raise_if_signalled()  # the handler was not ours: nothing noted
        assert seen == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_the_dropped_exception_is_not_printed_and_other_ones_are(monkeypatch):
    """The command ends with one line: the "Exception ignored in ..." traceback of a noted
    signal's dropped exception is not printed; any other unraisable exception still is."""
    heard: list[BaseException] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: heard.append(u.exc_value))
    with pytest.raises(KeyboardInterrupt), signals_raise():
        _drop_a_signal(signal.SIGINT)
    assert heard == []

    class Fails:
        def __del__(self) -> None:
            raise ValueError("a destructor's own error")

    with signals_raise():
        f = Fails()
        del f
        gc.collect()
    assert [type(e) for e in heard] == [ValueError]


def test_compiled_code_that_prints_the_dropped_exception_prints_nothing(monkeypatch):
    """Compiled code that cannot pass an exception on prints it with ``PyErr_PrintEx``, which
    goes through ``sys.excepthook`` (a Cython function: scipy's Sobol initialisation); a noted
    signal's exception is not printed, anything else still is."""
    heard: list[type[BaseException]] = []
    monkeypatch.setattr(sys, "excepthook", lambda t, e, tb: heard.append(t))
    with pytest.raises(KeyboardInterrupt), signals_raise():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # interrupted at once (the bound only matters if it is not)
        except KeyboardInterrupt as exc:  # what such code does with it: print, go on
            sys.excepthook(type(exc), exc, exc.__traceback__)
        try:
            raise ValueError("its own error")
        except ValueError as exc:
            sys.excepthook(type(exc), exc, exc.__traceback__)
        raise_if_signalled()
    assert heard == [ValueError]
    assert sys.excepthook is not None and signal.getsignal(signal.SIGINT) is \
        signal.default_int_handler
