"""How much runs at once: the one setting of the jobs, and the executors independent work runs on.

Independent work comes at three sizes, and each has one place here:

- **Within a stage** (the chunks of a compiled kernel, the five axes of the virtual machine or
  of a spline fit, the draws of a machine ensemble): threads, because the compiled loops and
  LAPACK release the interpreter lock and share the program's arrays without copying them.
  :func:`jobs` is how many; :func:`map_ordered` runs a sequence of such tasks with at most
  that many results in memory at once.
- **Whole programs** (a batch, a fleet): :func:`program_executor`, processes on this machine
  or a Dask distributed cluster (``dask://HOST:PORT``), one program per task; each task runs
  its own stages with one job, so the cores are not asked twice.

:func:`jobs` is process-wide, as numba's ``set_num_threads`` and BLAS's thread counts are:
the command line sets it once (``--jobs N``), the library with :func:`using_jobs`. Results do
not depend on it: every parallel piece of work is computed alone and put back in order.
"""

from __future__ import annotations

import os
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import contextmanager

from .errors import InputError

__all__ = ["jobs", "using_jobs", "default_jobs", "check_jobs", "map_ordered",
           "program_executor", "DASK_SCHEME"]

#: The ``--executor`` address prefix of a Dask distributed scheduler.
DASK_SCHEME = "dask://"
#: Seconds a Dask scheduler has to answer before ``--executor`` gives up.
DASK_CONNECT_SECONDS = 10

_jobs: int | None = None
_lock = threading.Lock()


def default_jobs() -> int:
    """All cores: ``NUMBA_NUM_THREADS`` where set (numba's own limit on its threads), else
    the number of cores."""
    value = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if value.isdigit() and int(value) > 0:
        return int(value)
    return max(1, os.cpu_count() or 1)


def check_jobs(value, field: str = "jobs") -> int:
    """``value`` as a number of jobs (a whole number >= 1), or a one-line error naming
    ``field``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(f"must be a whole number >= 1, got {value!r}", field=field)
    return value


def jobs() -> int:
    """How many pieces of independent work run at once in this process (default: all cores,
    :func:`default_jobs`)."""
    return _jobs if _jobs is not None else default_jobs()


@contextmanager
def using_jobs(n: int | None):
    """Run the enclosed work with ``n`` jobs (None: leave the setting as it is). Process-wide,
    like the thread counts of numba and BLAS: work started from other threads meanwhile sees
    it too."""
    global _jobs
    if n is None:
        yield jobs()
        return
    n = check_jobs(n)
    with _lock:
        before, _jobs = _jobs, n
    try:
        yield n
    finally:
        with _lock:
            _jobs = before


def map_ordered(function: Callable, items: Iterable, *, workers: int | None = None) -> Iterator:
    """``function(item)`` for each of ``items``, in order, on up to ``workers`` threads
    (default :func:`jobs`), a generator: at most ``workers`` results are computed ahead of the
    one the caller takes, so the memory held is that of ``workers`` results, however many items
    there are. With one worker, plain ``map``."""
    workers = jobs() if workers is None else check_jobs(workers, "workers")
    if workers <= 1:
        yield from map(function, items)
        return
    items = iter(items)
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="precontour-job") as pool:
        pending: deque = deque()
        try:
            for item in items:
                pending.append(pool.submit(function, item))
                if len(pending) >= workers:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for future in pending:
                future.cancel()


def program_executor(address: str | None = None, *, workers: int | None = None) -> Executor:
    """An executor for whole programs, one per task: ``address`` None, processes on this
    machine (``workers``, default :func:`jobs`; started by forkserver, clean of this process's
    threads); ``dask://HOST:PORT``, the workers of that Dask distributed scheduler (the
    ``distributed`` package: ``pip install 'precontour[dask]'``). Use it as a context manager;
    leaving it waits for the tasks and releases the processes or the client."""
    if address is None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        workers = jobs() if workers is None else check_jobs(workers, "workers")
        return ProcessPoolExecutor(max_workers=workers,
                                   mp_context=multiprocessing.get_context("forkserver"))
    if not address.startswith(DASK_SCHEME) or len(address) == len(DASK_SCHEME):
        raise InputError(f"must be {DASK_SCHEME}HOST:PORT (a Dask distributed scheduler), "
                         f"got {address!r}", field="--executor")
    try:
        from distributed import Client
    except ImportError:
        raise InputError("a Dask cluster needs the distributed package: pip install "
                         "'precontour[dask]'", field="--executor") from None
    try:
        client = Client(f"tcp://{address[len(DASK_SCHEME):]}", timeout=DASK_CONNECT_SECONDS)
    except (OSError, TimeoutError) as exc:
        raise InputError(f"no Dask scheduler answered at {address} within "
                         f"{DASK_CONNECT_SECONDS} s ({' '.join(str(exc).split())})",
                         field="--executor") from None
    return _DaskExecutor(client)


class _DaskExecutor(Executor):
    """A Dask client's ``concurrent.futures`` executor that closes the client when it is
    shut down (the client's own executor leaves it open)."""

    def __init__(self, client):
        self._client = client
        # pure=False: the same program run twice is two tasks, not one cached result
        self._executor = client.get_executor(pure=False)

    def submit(self, fn, /, *args, **kwargs):
        return self._executor.submit(fn, *args, **kwargs)

    def shutdown(self, wait=True, *, cancel_futures=False):
        try:
            self._executor.shutdown(wait=wait)
        finally:
            self._client.close()
