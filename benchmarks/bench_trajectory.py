"""Time trajectory generation of a synthetic 100,000-point five-axis CL path.

The path: the tool tip spirals over a dome (radius 10 -> 60 mm, 0.1 mm between points, about
10 m long) while the tool tilts between 0.3 and 0.9 rad and turns with the spiral. Run:

    PYTHONPATH=src python benchmarks/bench_trajectory.py [n_points]
"""

import sys
import time

import numpy as np

from precontour import load_machine
from precontour.trajectory.feedplan import plan_feed
from precontour.trajectory.pathspline import fit_toolpath
from precontour.toolpath import ToolPath
from precontour.trajectory.sampled import Trajectory
from precontour.trajectory.generate import summarize


def synthetic_path(n_points: int) -> ToolPath:
    u = np.linspace(0.0, 1.0, n_points)
    turns = 0.1 * n_points / (2 * np.pi * 35.0)  # ~0.1 mm spacing at the mean radius
    theta = 2 * np.pi * turns * u
    r = 10.0 + 50.0 * u
    P = np.stack([r * np.cos(theta), r * np.sin(theta), 30.0 * np.cos(r / 40.0)], axis=-1)
    A = 0.6 + 0.3 * np.sin(7 * theta / turns)
    C = theta + 0.4 * np.sin(3 * theta)
    O = np.stack([np.sin(A) * np.sin(C), -np.sin(A) * np.cos(C), np.cos(A)], axis=-1)
    return ToolPath(P=P, O=O, source="synthetic")


def main(n_points: int = 100_000) -> None:
    machine = load_machine("zhang2013")
    t0 = time.perf_counter()
    toolpath = synthetic_path(n_points)
    t1 = time.perf_counter()
    path = fit_toolpath(toolpath)
    t2 = time.perf_counter()
    profile = plan_feed(path, machine)
    t3 = time.perf_counter()
    tr = Trajectory(t=profile.t, q=profile.q, P=profile.P, O=profile.O)
    summary = summarize(tr, machine)
    t4 = time.perf_counter()
    print(f"{n_points} points, path length {path.length:.1f} mm, "
          f"{tr.n_samples} samples ({tr.duration:.2f} s), {profile.iterations} planning pass(es)")
    print(f"  make path      {t1 - t0:7.3f} s")
    print(f"  fit splines    {t2 - t1:7.3f} s")
    print(f"  plan feed      {t3 - t2:7.3f} s  (incl. sampling, IK and the limit check)")
    print(f"  summary        {t4 - t3:7.3f} s")
    print(f"  total          {t4 - t1:7.3f} s")
    print(summary)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
