"""Run independent tasks (candidate fits) in parallel: local processes or a Dask cluster.

* default: each task in its own forked process (``fork`` start method where the platform has it:
  children start at once with everything imported), at most ``workers`` at a time (default: the
  CPUs). A task that raises, dies, or runs past its time limit becomes a :class:`TaskFailed` (the
  process is killed) instead of stopping the others - a candidate model whose simulation never ends
  must not hang the whole diagnosis. The limit is ``timeout_s``, tightened once three tasks have
  finished to ``max(6 x the slowest finished task, 20 s)``; with ``costs`` (each task's expected
  relative cost) the 6 x is per unit of cost: ``6 x max(finished time / cost) x cost``, so a task
  known to be slower (a candidate whose simulation costs six times more) is not stopped for it.
  No task is stopped before it has run as long as the slowest finished task took: the cost is a
  short probe's, and a cheap probe must not give a fit less time than a typical one needs (the
  probe's cost does not bound the fit's: a fit's time also depends on where its parameters go;
  docs/decisions.md).
* ``in_process=True``: the tasks run one after the other in this process (no protection; for
  debugging and profiling).
* ``scheduler="tcp://host:port"`` (or a ``distributed.Client``): the tasks go to that Dask
  distributed cluster (``client.map``); tasks still running at the time limit are cancelled and
  reported as failed.

Results come back in task order; ``on_done(index, result)`` is called as each finishes.

Each local worker runs one BLAS thread (``threadpoolctl``): numpy's OpenBLAS otherwise keeps a pool
of one thread per core in every worker, and 2 workers ran 4 busy threads on 2 cores. The workers
are the parallelism. A Dask worker process has one already (its nanny starts it with
``OPENBLAS_NUM_THREADS=1``, Dask's ``distributed.nanny.pre-spawn-environ``).

No worker outlives :func:`run_tasks` (local processes):

* a worker that has sent its result but does not exit within ``EXIT_GRACE_S`` (a thread it started
  keeps it alive, a lock it inherited through ``fork`` never frees) is killed;
* workers ignore SIGINT: Ctrl-C at a terminal goes to the whole process group, and it is the parent
  that stops (``KeyboardInterrupt``) and kills every worker it started on its way out;
* SIGTERM to the parent, while tasks run in its main thread with the default SIGTERM action,
  raises :class:`~rigctl.workbench.interrupts.Terminated` (a ``KeyboardInterrupt``) instead of
  ending the process on the spot, so the workers are killed the same way; the CLI prints
  ``rigctl: terminated`` and exits 143. A Ctrl-C or SIGTERM whose exception Python dropped (raised
  inside a destructor) is raised again at the loop's next turn (:mod:`rigctl.workbench.interrupts`);
* on Linux each worker asks the kernel to SIGKILL it when its parent dies
  (``prctl(PR_SET_PDEATHSIG)``), so even a parent killed with SIGKILL leaves no worker behind.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import ctypes.util
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

from rigctl.errors import InputError
from rigctl.workbench.interrupts import raise_if_signalled, signals_raise

T = TypeVar("T")
R = TypeVar("R")

DEFAULT_TIMEOUT_S = 300.0  # a candidate fit past five minutes is reported as timed out
ADAPTIVE_FACTOR = 6.0  # a fit may take this many times the finished ones (scaled by its cost)
ADAPTIVE_FLOOR_S = 20.0  # ... but never less than this: no fit is stopped in its first seconds


CONNECT_TIMEOUT_S = 30.0
EXIT_GRACE_S = 2.0  # a worker that sent its result has this long to exit before it is killed
PR_SET_PDEATHSIG = 1  # linux/prctl.h

_clock: Callable[[], float] = time.monotonic
"""The clock of the local workers' time limits (seconds; a test replaces it to run the limits in
virtual time)."""


class SchedulerError(InputError):
    """The Dask scheduler cannot be reached (a usage problem: one line, exit code 2)."""


@dataclass(frozen=True)
class TaskFailed:
    """A task that raised, died or was stopped at its time limit."""

    message: str


def default_workers() -> int:
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    *,
    workers: int | None = None,
    scheduler: Any = None,
    on_done: Callable[[int, R | TaskFailed], None] | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    in_process: bool = False,
    costs: Sequence[float] | None = None,
) -> list[R | TaskFailed]:
    if not tasks:
        return []
    if scheduler is not None:
        return _run_dask(fn, tasks, scheduler, on_done, timeout_s)
    if in_process:
        out: list[R | TaskFailed] = []
        for i, task in enumerate(tasks):
            res: R | TaskFailed = fn(task)
            if on_done:
                on_done(i, res)
            out.append(res)
        return out
    if costs is not None and len(costs) != len(tasks):
        raise ValueError(f"{len(costs)} costs for {len(tasks)} tasks")
    rel = [c if c > 0 and c == c else 1.0 for c in costs] if costs is not None \
        else [1.0] * len(tasks)
    return _run_processes(fn, tasks, workers or default_workers(), on_done, timeout_s, rel)


def _child(fn: Callable[[Any], Any], task: Any, conn: Connection, parent_pid: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the parent's Terminated handler
    die_with_parent(parent_pid)
    threadpool_limits(1)  # for the worker's life: it is one of the parallel tasks
    try:
        payload: tuple[str, Any] = ("ok", fn(task))
    except BaseException as exc:  # report anything, the parent decides
        payload = ("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}")
    try:
        conn.send(payload)
    except BrokenPipeError:  # the parent has gone: nobody to tell
        os._exit(1)
    except Exception as exc:  # e.g. an unpicklable result
        conn.send(("error", f"cannot return the result: {exc}"))
    conn.close()


def die_with_parent(parent_pid: int) -> None:
    """Linux: have the kernel SIGKILL this process when its parent dies (whatever kills the parent,
    SIGKILL included); if the parent is already gone, exit now. Elsewhere nothing is done: the
    parent's clean-up (``finally`` and multiprocessing's exit handler for daemon processes) is all
    there is. Called first thing in a worker process: this module's task processes and the
    search's evaluation pool (:mod:`rigctl.workbench.search_pool`)."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError, TypeError):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:
        os._exit(1)


def _reap(proc: Any) -> None:
    """Wait briefly for a worker to exit; kill it if it does not."""
    proc.join(timeout=EXIT_GRACE_S)
    if proc.exitcode is None:
        proc.kill()
        proc.join(timeout=5)


def _run_processes(
    fn: Callable[[T], R], tasks: Sequence[T], workers: int,
    on_done: Callable[[int, R | TaskFailed], None] | None, timeout_s: float,
    costs: Sequence[float],
) -> list[R | TaskFailed]:
    methods = multiprocessing.get_all_start_methods()
    ctx: Any = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    results: list[Any] = [None] * len(tasks)
    todo = list(range(len(tasks)))
    running: dict[int, tuple[Any, Connection, float]] = {}
    started: list[Any] = []  # every worker, for the clean-up whatever interrupts the loop
    finished_times: list[float] = []  # per unit of expected cost
    slowest_s = 0.0  # the longest a finished task took: no task is stopped before it

    def finish(i: int, value: R | TaskFailed) -> None:
        results[i] = value
        if on_done:
            on_done(i, value)

    with signals_raise(), contextlib.ExitStack() as cleanup:
        cleanup.callback(_kill_all, started, running)
        while todo or running:
            while todo and len(running) < max(1, workers):
                i = todo.pop(0)
                recv, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_child, args=(fn, tasks[i], send, os.getpid()),
                                   daemon=True)
                started.append(proc)
                proc.start()
                send.close()
                running[i] = (proc, recv, _clock())
            ready = wait([c for _, c, _ in running.values()], timeout=0.2)
            raise_if_signalled()  # a Ctrl-C whose exception a destructor dropped
            now = _clock()
            for i in list(running):
                proc, conn, t0 = running[i]
                if conn in ready:
                    try:
                        status, value = conn.recv()
                    except EOFError:
                        status, value = "error", f"worker died (exit code {proc.exitcode})"
                    conn.close()
                    _reap(proc)
                    del running[i]
                    finished_times.append((now - t0) / costs[i])
                    slowest_s = max(slowest_s, now - t0)
                    finish(i, value if status == "ok" else TaskFailed(str(value)))
                    continue
                limit = timeout_s
                if len(finished_times) >= 3:
                    limit = min(limit, max(ADAPTIVE_FACTOR * max(finished_times) * costs[i],
                                           slowest_s, ADAPTIVE_FLOOR_S))
                if now - t0 > limit:
                    proc.kill()
                    proc.join(timeout=5)
                    conn.close()
                    del running[i]
                    finish(i, TaskFailed(f"stopped after {now - t0:.0f} s (time limit)"))
    return results


def _kill_all(started: Sequence[Any], running: dict[int, tuple[Any, Connection, float]]) -> None:
    """Kill every worker still alive (those started but not yet registered as running too) and
    wait for each, so none is left behind, not even as a zombie."""
    for proc in started:
        if proc.pid is not None and proc.exitcode is None:
            with contextlib.suppress(OSError, ValueError):
                proc.kill()
    for proc in started:
        if proc.pid is not None:
            with contextlib.suppress(OSError, ValueError, AssertionError):
                proc.join(timeout=5)
    for _, conn, _ in running.values():
        conn.close()


def connect(address: str, timeout_s: float = CONNECT_TIMEOUT_S, security: Any = None) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address`` (SchedulerError if unreachable or
    silent for ``timeout_s``); ``security`` a ``distributed.Security`` for a ``tls://`` scheduler
    (docs/workbench.md).

    The scheduler is first asked for Dask's handshake within ``timeout_s``: ``Client(timeout=)``
    bounds the TCP connection but not the handshake read after it, so a port that accepts and
    never answers hung the command with no word (distributed 2026.8, ``comm.core.connect``)."""
    from distributed import Client

    try:
        asyncio.run(_handshake(address, timeout_s, security))
    except TimeoutError:
        raise SchedulerError(f"the Dask scheduler at {address} did not answer within "
                             f"{timeout_s:g} s (is it a Dask scheduler, and is it running?)") from None
    except (OSError, TypeError, ValueError) as exc:  # TypeError: tls:// without TLS
        raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {exc}") from exc
    try:
        return Client(address, timeout=timeout_s, security=security)
    except (OSError, TimeoutError, TypeError, ValueError) as exc:
        raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {exc}") from exc


async def _handshake(address: str, timeout_s: float, security: Any) -> None:
    """Open a Dask connection to ``address`` and close it; TimeoutError past ``timeout_s``."""
    from distributed.comm import connect as dask_connect

    kwargs = security.get_connection_args("client") if security is not None else {}
    comm = await asyncio.wait_for(dask_connect(address, timeout=timeout_s, **kwargs), timeout_s)
    await comm.close()


REMOTE_CALL_TIMEOUT_S = 60.0
"""Longest wait for one call to the cluster after the tasks ran: a finished task's result, closing
the client (a scheduler that stops answering must not hang the command)."""


def _run_dask(
    fn: Callable[[T], R], tasks: Sequence[T], scheduler: Any,
    on_done: Callable[[int, R | TaskFailed], None] | None, timeout_s: float,
) -> list[R | TaskFailed]:
    from distributed import Client, as_completed
    from distributed.client import Future

    own = not isinstance(scheduler, Client)
    client = connect(scheduler, min(timeout_s, CONNECT_TIMEOUT_S)) if own else scheduler
    where = f"the Dask scheduler at {getattr(client.scheduler, 'address', scheduler)}"
    with signals_raise(), contextlib.ExitStack() as cleanup:
        if own:
            cleanup.callback(client.close, timeout=REMOTE_CALL_TIMEOUT_S)
        futures: list[Future] = client.map(fn, list(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results: list[Any] = [None] * len(tasks)
        done_keys: set[Any] = set()
        try:
            for fut in as_completed(futures, timeout=timeout_s):
                raise_if_signalled()  # a Ctrl-C whose exception a destructor dropped
                i = index[fut.key]
                done_keys.add(fut.key)
                try:
                    value: R | TaskFailed = fut.result(timeout=REMOTE_CALL_TIMEOUT_S)
                except TimeoutError:
                    value = TaskFailed(f"its result did not come from {where} within "
                                       f"{REMOTE_CALL_TIMEOUT_S:.0f} s")
                except Exception as exc:
                    value = TaskFailed(f"{type(exc).__name__}: {exc}")
                results[i] = value
                if on_done:
                    on_done(i, value)
        except TimeoutError:
            pass
        except BaseException:  # Ctrl-C, SIGTERM: take our tasks off the cluster
            with contextlib.suppress(Exception):
                client.cancel(futures)
            raise
        for fut in futures:
            if fut.key not in done_keys:
                fut.cancel()
                i = index[fut.key]
                results[i] = TaskFailed(f"not finished on the cluster within {timeout_s:.0f} s")
                if on_done:
                    on_done(i, results[i])
        return results
