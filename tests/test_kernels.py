"""The compiled kernels' shared machinery: the note before the first compile (once, only on a
cold cache, never for --help) and the threads over chunks."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from precontour import kernels

NOTE_START = "precontour: note: compiling numerical kernels, once after installing: about "

#: Calls two small kernels (C unwrapped as numpy.unwrap, the program writer's decimation):
#: cheap to compile, so a cold cache costs the test about a second.
TWO_KERNELS = (
    "import numpy as np\n"
    "from precontour.machine.kinematics._trunnion import _unwrap\n"
    "from precontour.toolpath.writers import decimate\n"
    "_unwrap(np.linspace(0.0, 20.0, 50), 2 * np.pi)\n"
    "print('first done', flush=True)\n"
    "t = np.linspace(0.0, 1.0, 20)\n"
    "decimate(t, np.column_stack([t] * 5), np.full(5, 1e-3))\n"
    "print('second done', flush=True)\n"
)


def _run(args, cache) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          check=True, timeout=600)


def _notes(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("precontour: note:")]


def test_note_once_on_a_cold_cache_and_never_on_a_warm_one(tmp_path):
    cold = _run(["-c", TWO_KERNELS], tmp_path / "cache")
    notes = _notes(cold.stderr)
    assert len(notes) == 1, cold.stderr                 # two kernels compiled, one line
    assert notes[0].startswith(NOTE_START) and notes[0].endswith(" s"), notes
    assert int(notes[0][len(NOTE_START):-2]) > 0
    assert cold.stdout.splitlines() == ["first done", "second done"]
    warm = _run(["-c", TWO_KERNELS], tmp_path / "cache")
    assert warm.stderr == "" and warm.stdout == cold.stdout


def test_no_note_and_no_compiling_for_help(tmp_path):
    for args in (["-m", "precontour", "--help"], ["-m", "precontour", "demo", "--help"]):
        out = _run(args, tmp_path / "cache")
        assert out.stderr == "", out.stderr
        assert "usage" in out.stdout
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").rglob("*.nbi"))


@pytest.mark.parametrize("n_chunks, grain", [(0, 1), (1, 1), (7, 1), (64, 1), (10, 4)])
def test_run_chunks_covers_every_chunk_once(n_chunks, grain):
    seen = np.zeros(n_chunks, dtype=int)
    calls = []

    def kernel(first, stop, out):
        calls.append((first, stop))
        out[first:stop] += 1

    kernels.run_chunks(kernel, n_chunks, seen, grain=grain)
    assert (seen == 1).all()
    assert len(calls) <= max(1, min(kernels.threads(), -(-n_chunks // grain)))
    assert all(stop > first for first, stop in calls) or n_chunks == 0


def test_run_chunks_passes_a_kernels_error_on():
    def kernel(first, stop):
        if first > 0 or stop == 1:
            raise ValueError("chunk failed")

    with pytest.raises(ValueError, match="chunk failed"):
        kernels.run_chunks(kernel, 8)


def test_every_kernel_module_has_a_compile_estimate():
    import importlib
    import pkgutil

    import precontour

    for module in pkgutil.walk_packages(precontour.__path__, "precontour."):
        if module.name != "precontour.__main__":
            importlib.import_module(module.name)
    modules = {dispatcher.py_func.__module__ for dispatcher in kernels._kernels}
    assert "precontour.prediction.contour" in modules
    assert modules <= set(kernels.COMPILE_SECONDS), modules - set(kernels.COMPILE_SECONDS)
    assert 0 <= kernels.compile_seconds_left() <= sum(kernels.COMPILE_SECONDS.values())


def test_run_chunks_in_a_forked_child():
    # the parent's pool threads do not exist in a fork: the child makes its own pool
    import multiprocessing

    out = np.zeros(64)
    kernels.run_chunks(_fill, 64, out)            # the parent's pool exists now
    context = multiprocessing.get_context("fork")
    with context.Pool(1) as pool:
        assert pool.apply_async(_fill_in_child).get(timeout=60) == 64.0


def _fill(first, stop, out):
    out[first:stop] = 1.0


def _fill_in_child():
    out = np.zeros(64)
    kernels.run_chunks(_fill, 64, out)
    return float(out.sum())
