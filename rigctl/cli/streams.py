"""Standard output whose reader has gone (a closed pipe, a hung-up terminal).

``rigctl info run.h5 | head -1`` closes the pipe after one line: not an error of the command's.
A run is different: what it prints before motion (the plan) is what the operator or the scheduler
sees of what the rig is about to do, and what it prints after (the outcome) must not be lost nor
change its exit code. :func:`show` prints and says whether stdout could still be written (once
not, stdout goes to /dev/null, so that no later flush fails again); :func:`report` writes the
outcome to stdout, or to stderr once stdout has gone.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterable


def discard_stdout() -> None:
    """Send stdout to /dev/null from now on (what is still buffered included): the interpreter's
    own final flush then cannot fail on a closed pipe."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def stdout_gone() -> bool:
    """Flush stdout; True if its reader has gone (broken pipe, hung-up terminal), and stdout then
    goes to /dev/null."""
    try:
        sys.stdout.flush()
    except (OSError, ValueError):  # BrokenPipeError; EIO from a hung-up terminal; closed file
        discard_stdout()
        return True
    return False


def show(lines: Iterable[str]) -> bool:
    """Print ``lines`` to stdout now (flushed); False if its reader has gone (nothing more goes
    to it)."""
    try:
        for line in lines:
            print(line)
    except (OSError, ValueError):
        discard_stdout()
        return False
    return not stdout_gone()


def say(text: str) -> None:
    """One line on stderr, dropped if stderr is gone too."""
    with contextlib.suppress(OSError, ValueError):
        print(text, file=sys.stderr, flush=True)


def report(lines: Iterable[str]) -> None:
    """Lines for stdout; all of them to stderr instead if stdout has gone (a line that seemed
    written may have sat in the buffer of a pipe nobody reads)."""
    pending = list(lines)
    try:
        for line in pending:
            print(line)
        sys.stdout.flush()
        return
    except (OSError, ValueError):
        discard_stdout()
    say("(standard output is closed: the run's report goes here)")
    for line in pending:
        say(line)
