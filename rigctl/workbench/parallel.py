"""Worker processes: how many, and that none outlives the process that started it.

The search evaluates its points in a pool of worker processes (:mod:`rigctl.workbench.search_pool`);
this module holds what the pool and the commands share: the default number of workers (the CPUs
this process may run on) and the kernel's guarantee that a worker dies with its parent.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import signal
import sys

DEFAULT_TIMEOUT_S = 300.0
"""A fit's time limit after the model's own (``diagnose --timeout``): five minutes, at which a fit
ends with its best point so far."""
PR_SET_PDEATHSIG = 1  # linux/prctl.h


def default_workers() -> int:
    """The CPUs this process may run on (its affinity mask where the platform has one)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def die_with_parent(parent_pid: int) -> None:
    """Linux: have the kernel SIGKILL this process when its parent dies (whatever kills the parent,
    SIGKILL included); if the parent is already gone, exit now. Elsewhere nothing is done: the
    parent's clean-up (``finally`` and multiprocessing's exit handler for daemon processes) is all
    there is. Called first thing in a worker process of the search's evaluation pool
    (:mod:`rigctl.workbench.search_pool`)."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError, TypeError):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:
        os._exit(1)
