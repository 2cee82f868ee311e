"""Run independent jobs in worker processes, forwarding their progress and honouring a cancel event.

Multi-start chains are independent once their seeds are fixed, so they can run on every core at
once: the results are the same for any number of workers. A job is ``fn(job, callback, cancel)``;
in a worker, ``callback`` puts its argument on a queue that the calling process drains into the
caller's callback, and ``cancel`` is a process-shared event set when the caller's event is.

Workers are forked on Linux (the parent's compiled numba kernels come along; nothing to reload)
and spawned elsewhere or once numba's thread pool runs in this process. They ignore SIGINT:
Ctrl-C reaches the caller, which sets the shared event, so every job stops between generations
and returns its partial state.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, Protocol

from core.kinematics.memory import keep_freed_memory


class Flag(Protocol):
    def is_set(self) -> bool: ...


Job = Callable[[Any, Callable[[Any], None] | None, Flag | None], Any]

_QUEUE: Any = None
_STOP: Any = None


def available() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def resolve(workers: int | None, n_jobs: int) -> int:
    """Worker processes for ``n_jobs`` jobs: ``workers`` (None or 0: every available core), at most one per job."""
    w = available() if not workers else int(workers)
    return max(1, min(w, n_jobs))


def start_method() -> str:
    """``fork`` where the platform has it, unless numba's thread pool already runs here (its threads
    do not survive a fork): then ``spawn``, which starts workers afresh (slower, always safe)."""
    from numba.np.ufunc import parallel

    if "fork" in mp.get_all_start_methods() and not getattr(parallel, "_is_initialized", False):
        return "fork"
    return "spawn"


PR_SET_PDEATHSIG = 1
PARENT_POLL = 1.0  # s between checks that the parent still lives (where prctl is missing)


def die_with_parent(parent: int) -> None:
    """Make this worker process end when ``parent`` does (killed, crashed): no orphan holding memory.

    Linux sends SIGTERM through ``prctl(PR_SET_PDEATHSIG)``; a daemon thread also polls the parent pid
    (any platform, and the moment between fork and prctl).
    """
    if sys.platform.startswith("linux"):  # ctypes.CDLL(None) is a TypeError on Windows
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while True:
            if os.getppid() != parent:
                os._exit(1)
            threading.Event().wait(PARENT_POLL)

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _init(q: Any, stop: Any, parent: int) -> None:
    global _QUEUE, _STOP
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    keep_freed_memory()  # a spawned worker starts with glibc's defaults
    _QUEUE, _STOP = q, stop


def _call(fn: Job, i: int, job: Any, report: bool) -> Any:
    def forward(item: Any) -> None:
        _QUEUE.put((i, item))

    try:
        return fn(job, forward if report else None, _STOP)
    finally:
        _QUEUE.put((i, _DONE))


class _Done:
    """End-of-job marker: the job's progress items all came before it (one queue per producer is ordered)."""

    def __reduce__(self) -> str:
        return "_DONE"


_DONE = _Done()


class _ClusterFlag:
    """The cancel flag of a job on a Dask cluster: a named distributed Event, looked up where the job runs."""

    def __init__(self, name: str) -> None:
        self.name = name

    def is_set(self) -> bool:
        from distributed import Event

        return bool(Event(self.name).is_set())


def _cluster_call(fn: Job, job: Any, flag: str) -> Any:
    return fn(job, None, _ClusterFlag(flag))


def connect(scheduler: str, timeout: str = "20s") -> Any:
    """A ``distributed.Client`` of the Dask scheduler at ``scheduler``; ValueError (one line for the CLI and the
    studio) when none answers there within ``timeout``."""
    from distributed import Client

    try:
        return Client(scheduler, timeout=timeout)
    except OSError as e:  # distributed's "Timed out trying to connect ..." and refused connections
        raise ValueError(f"no Dask scheduler answers at {scheduler} ({e})") from None
    except ValueError as e:  # "missing port number in address 'foo'", in Dask's words only (review of session 33)
        raise ValueError(f"{scheduler!r} is not a Dask scheduler address ({e}); one reads like "
                         "tcp://127.0.0.1:8786") from None


def run_on_cluster(fn: Job, jobs: Sequence[Any], scheduler: str, cancel: threading.Event | None = None) -> list[Any]:
    """``[fn(job, None, cancel) for job in jobs]`` as tasks on the Dask scheduler at ``scheduler``.

    The jobs see the caller's ``cancel`` through a distributed Event (one scheduler round trip per check);
    their progress is not forwarded (a cluster's workers report when each job ends).
    """
    import uuid

    from distributed import Event

    with connect(scheduler) as client:
        name = f"clm-cancel-{uuid.uuid4().hex}"
        event = Event(name, client=client)
        futures = client.map(_cluster_call, [fn] * len(jobs), list(jobs), [name] * len(jobs), pure=False)
        try:
            while not all(f.done() for f in futures):
                if cancel is not None and cancel.is_set():
                    event.set()
                threading.Event().wait(0.05)
            return list(client.gather(futures))
        finally:
            event.set()


def run(fn: Job, jobs: Sequence[Any], workers: int | None = None, callback: Callable[[Any], None] | None = None,
        cancel: threading.Event | None = None, scheduler: str | None = None) -> list[Any]:
    """``[fn(job, callback, cancel) for job in jobs]``, in up to ``workers`` processes.

    Args:
        fn: a module-level function (workers import it by name).
        jobs: picklable arguments.
        workers: processes (None or 0: every available core); 1 runs the jobs here, in order,
            skipping none (a job sees ``cancel`` itself).
        callback: gets every item a job reports, in the calling thread (items of one job in order).
        cancel: once set, the workers' shared event is set too.

    Returns:
        The jobs' return values, in job order.

    Raises:
        The first exception a job raised (the others are told to stop).

    With ``scheduler`` (a Dask scheduler address) the jobs run on that cluster instead (``run_on_cluster``).
    """
    if scheduler:
        return run_on_cluster(fn, jobs, scheduler, cancel)
    n = resolve(workers, len(jobs))
    if n == 1:
        return [fn(job, callback, cancel) for job in jobs]
    ctx = mp.get_context(start_method())
    q, stop = ctx.Queue(), ctx.Event()
    pool = ProcessPoolExecutor(n, mp_context=ctx, initializer=_init, initargs=(q, stop, os.getpid()))
    try:
        futures = [pool.submit(_call, fn, i, job, callback is not None) for i, job in enumerate(jobs)]
        done = 0
        while done < len(jobs):
            if cancel is not None and cancel.is_set():
                stop.set()
            _raise_failed(futures, stop)
            try:
                i, item = q.get(timeout=0.05)
            except queue.Empty:
                continue
            if isinstance(item, _Done):
                done += 1
            elif callback is not None:
                callback(item)
        return [f.result() for f in futures]
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)


def _raise_failed(futures: Sequence[Future[Any]], stop: Any) -> None:
    # Fail at once: the other jobs are told to stop (and a worker that died never sends its end marker).
    for f in futures:
        if f.done() and f.exception() is not None:
            stop.set()
            raise f.exception()  # type: ignore[misc]
