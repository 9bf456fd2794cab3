"""Where the time of ``compensate`` and ``run`` goes, at 10^6 samples: a profile by stage.

``compensate`` with its defaults (limits kept, ``precontour.compensate(servo, traj)``) on the
synthetic trajectory of ``bench_pipeline.py`` (about 10^6 samples, ``zhang2013`` /
``pid-high``), and ``run`` on the same path written as CL data, each under ``cProfile`` in its
own process after a warm-up (compiled code loaded, not compiled). For each, the wall time,
the CPU time over the wall time (how many cores were busy on average), and the functions of
the package that take the most time with what they call, cumulative: the stages, and within
them what is repeated (the call counts). The baseline, measured in the same run, is
``scipy.signal.lsim`` of the five closed loops on the same samples.

Run: ``python benchmarks/bench_profile.py [--samples 1e6] [--top 25] [--jobs N]``.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

CONTROLLER = "pid-high"
COMMANDS = ("lsim of the 5 loops", "compensate (defaults)", "run (defaults)")


def _job(name: str, traj, folder: Path):
    """The command as a function of nothing, on ``traj``."""
    from scipy import signal

    import precontour
    from precontour.workflow import RunOutputs, run_program

    servo = precontour.load_servo("zhang2013", CONTROLLER)
    if name == "lsim of the 5 loops":
        return lambda: [signal.lsim((m.num, m.den), traj.q[:, i] - traj.q[0, i], traj.t)
                        for i, m in enumerate(servo.models)]
    if name == "compensate (defaults)":
        return lambda: precontour.compensate(servo, traj)
    if name == "run (defaults)":
        program = folder / f"path-{traj.n_samples}.csv"
        np.savetxt(program, np.column_stack([traj.P[::50], traj.O[::50]]), delimiter=",",
                   header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.9f")
        return lambda: run_program(program, RunOutputs(program=folder / "out.ngc"),
                                   machine="zhang2013", controller=CONTROLLER)
    raise ValueError(name)


def _profile(name: str, n_samples: int, top: int) -> None:
    """In a child process: warm up, then the command once under cProfile; print a JSON line
    with its wall and CPU seconds, and the profile's top functions."""
    from bench_pipeline import _trajectory

    with tempfile.TemporaryDirectory() as folder:
        _job(name, _trajectory(10_000), Path(folder))()
        job = _job(name, _trajectory(n_samples), Path(folder))
        profile = cProfile.Profile()
        wall, cpu = time.perf_counter(), time.process_time()
        profile.runcall(job)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    text = io.StringIO()
    stats = pstats.Stats(profile, stream=text)
    stats.sort_stats("cumulative").print_stats("precontour", top)
    import precontour

    # the package's files named from its folder (precontour/...), wherever it is installed
    root = str(Path(precontour.__file__).parent.parent) + os.sep
    lines = [line.replace(root, "") for line in text.getvalue().splitlines()
             if "precontour" in line and "{" not in line and "List reduced" not in line]
    print(json.dumps({"wall": wall, "cpu": cpu, "lines": lines}))


def _child(*args: str) -> dict:
    from bench_pipeline import run_child

    return run_child(__file__, *args)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e6)
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--child", nargs=2, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _profile(args.child[0], int(float(args.child[1])), args.top)
        return
    n = int(args.samples)
    print(f"about {n:,} samples, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.2f} at the start")
    baseline = None
    for name in COMMANDS:
        result = _child("--child", name, str(n), "--top", str(args.top))
        baseline = baseline or result["wall"]
        print(f"\n## {name}: {result['wall']:.1f} s wall, lsim's time over it "
              f"{baseline / result['wall']:.2f}, CPU / wall {result['cpu'] / result['wall']:.2f}")
        if name != COMMANDS[0]:
            print("   ncalls  tottime  percall  cumtime  percall function (cumulative)")
            print("\n".join(result["lines"]))


if __name__ == "__main__":
    main()
