"""Running the compiled numerical kernels: the note before they compile, and their threads.

The per-sample loops of every stage are numba functions cached on disk (``cache=True``): the
first call after installing compiles them, later runs load them. This module owns what the
kernels' modules share about that:

- :func:`jit`, the one decorator of every kernel (compiled lazily, on its first call, with the
  options the project uses; ``nogil`` so that :func:`run_chunks` can run it on threads).
  Small helpers called per sample are inlined, preferably by LLVM (``forceinline=True``):
  numba's own inlining (``inline="always"``) types and compiles a copy at every call site.
  That is still the choice for a helper called with constant arguments, which numba would
  otherwise compile once more for each constant's value.
- A listener on numba's compile events that prints one line to stderr before the first kernel
  of the package compiles (:data:`NOTE`), so a first run does not look hung. numba only
  raises the event when a kernel is not in its cache, so a run on a warm cache prints nothing.
- :func:`run_chunks`, which spreads a kernel over chunks of samples on a few threads. Kernels
  used to do that with ``parallel=True``; numba's parallel loops cost seconds each to
  compile, a thread pool nothing (the kernels release the GIL).
"""

from __future__ import annotations

import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
from numba.core import event

from .parallel import jobs

__all__ = ["jit", "run_chunks", "NOTE", "before_note", "print_note", "compile_seconds_left",
           "threads"]

#: The line printed before the first kernel compiles; ``{seconds}`` is
#: :func:`compile_seconds_left` rounded.
NOTE = "precontour: note: compiling numerical kernels, once after installing: about {seconds} s"

#: CPU seconds each module's kernels take to compile, all of them (``benchmarks/
#: bench_compile.py``: the demo on an empty cache, the best of three runs at load average 3 on
#: the project's 2-core machine; the program writer's one kernel estimated). The note's
#: estimate counts the modules whose kernels are not in the cache.
COMPILE_SECONDS: dict[str, float] = {
    "precontour.prediction.contour": 5.0,        # 4.0 before its sample tree (+0.8 s measured)
    "precontour.trajectory.pathspline": 2.8,
    "precontour.trajectory.feedplan": 2.8,
    "precontour.simulation._integrators": 2.5,   # the virtual machine's time loops
    "precontour.piecewise": 2.1,
    "precontour.simulation.control_laws": 2.0,
    "precontour.prediction.tracking": 1.7,
    "precontour.prediction.splinefit": 1.3,
    "precontour.machine.kinematics._trunnion": 0.2,
    "precontour.toolpath.writers": 0.3,
}

_kernels: list = []          # every dispatcher made by jit, for the estimate
_noted = False
_note_lock = threading.Lock()


def jit(function=None, **options):
    """``numba.njit`` with the project's options: cached on disk, compiled on first call,
    releasing the GIL. Extra ``options`` go to numba (``forceinline``, ``inline``,
    ``error_model``)."""
    options = {"cache": True, "nogil": True, **options}

    def decorate(f):
        dispatcher = numba.njit(**options)(f)
        _kernels.append(dispatcher)
        return dispatcher

    return decorate(function) if function is not None else decorate


def _cached(dispatcher) -> bool:
    """Whether numba's cache holds an index for ``dispatcher`` (any signature). numba does not
    say so publicly; without its cache object this counts the kernel as not cached."""
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)
    except AttributeError:
        return False


def compile_seconds_left() -> float:
    """Estimated seconds to compile the package's kernels that are not in numba's cache:
    each module's :data:`COMPILE_SECONDS` times the share of its kernels not cached."""
    total: dict[str, int] = {}
    missing: dict[str, int] = {}
    for dispatcher in _kernels:
        module = dispatcher.py_func.__module__
        total[module] = total.get(module, 0) + 1
        missing[module] = missing.get(module, 0) + (not _cached(dispatcher))
    return sum(COMPILE_SECONDS.get(module, 0.5) * missing[module] / total[module]
               for module in total)


#: Called before the note is printed, e.g. by a progress display that keeps an unfinished
#: line on the terminal, to end it (weak references to bound methods or functions).
before_note: list = []


def print_note() -> None:
    """Print :data:`NOTE` to stderr, after the :data:`before_note` callbacks."""
    for ref in list(before_note):
        callback = ref()
        if callback is not None:
            callback()
    seconds = max(5, 5 * round(compile_seconds_left() / 5))
    print(NOTE.format(seconds=seconds), file=sys.stderr, flush=True)


class _Note(event.Listener):
    """Prints :data:`NOTE` when the first kernel of the package starts compiling."""

    def on_start(self, ev):
        global _noted
        if _noted or not ev.data["dispatcher"].py_func.__module__.startswith("precontour."):
            return
        with _note_lock:
            if _noted:
                return
            _noted = True
        print_note()

    def on_end(self, ev):
        pass


event.register("numba:compile", _Note())


def threads() -> int:
    """Threads :func:`run_chunks` uses: the jobs setting (:func:`precontour.parallel.jobs`,
    ``--jobs``; default all cores)."""
    return jobs()


_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_lock = threading.Lock()


def _forget_pool() -> None:
    """In a forked child: the parent's pool threads do not exist there."""
    global _pool, _pool_size, _pool_lock
    _pool, _pool_size, _pool_lock = None, 0, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def run_chunks(kernel, n_chunks: int, *args, grain: int = 1) -> None:
    """``kernel(first, stop, *args)`` for consecutive ranges [first, stop) of chunk indices
    covering [0, n_chunks), on up to :func:`threads` threads (the caller's among them), each
    given at least ``grain`` chunks. A kernel's results must not depend on how the chunks are
    split: each chunk is computed alone, as the iterations of a parallel loop were."""
    global _pool, _pool_size
    workers = min(threads(), -(-n_chunks // grain))
    if workers <= 1:
        kernel(0, n_chunks, *args)
        return
    bounds = [n_chunks * w // workers for w in range(workers + 1)]
    with _pool_lock:
        if _pool_size < workers - 1:
            _pool = ThreadPoolExecutor(max_workers=workers - 1,
                                       thread_name_prefix="precontour-kernel")
            _pool_size = workers - 1
        pool = _pool
    futures = [pool.submit(kernel, bounds[w], bounds[w + 1], *args) for w in range(1, workers)]
    try:
        kernel(bounds[0], bounds[1], *args)
    finally:
        # every chunk finishes (or fails) before the caller goes on, whatever happened here
        errors = [future.exception() for future in futures]
    for error in errors:
        if error is not None:
            raise error
