"""Speed and memory of NC programs through `precontour trajectory` (a script, not a test).

Writes a synthetic five-axis CAM program in TCP mode with inverse-time feeds (the way the
public trunnion examples are written): N blocks of 0.1 s each along a spiral over a dome,
with the tool tilting and turning, a rapid retract/approach (rotate first, then position) every
500 blocks, an arc and a helix between passes. Then it times, in the same run:

- reading the program (`read_program`) and timing it (`program_trajectory`), with the peak
  resident memory of that part;
- the baseline: trajectory generation of a 100,000-point CL path (`generate_trajectory`, the
  path spline + feed planner, as in bench_trajectory.py), and prints the ratios of the times
  and of the costs per sample.

    PYTHONPATH=src python benchmarks/bench_program.py [N_BLOCKS]   (default 10,000: 10^6 samples)
    PYTHONPATH=src python benchmarks/bench_program.py --file PROGRAM.ngc [--tcp]
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from precontour import load_machine
from precontour.toolpath import read_program
from precontour.trajectory import generate_trajectory, program_trajectory

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_trajectory import synthetic_path  # noqa: E402


def write_program(path: Path, n_blocks: int) -> None:
    u = np.linspace(0.0, 1.0, n_blocks)
    theta = 2 * np.pi * 25 * u
    r = 10.0 + 30.0 * u
    tip = np.column_stack([r * np.cos(theta), r * np.sin(theta), 5.0 * np.cos(r / 10.0)])
    a = -30.0 - 20.0 * np.sin(3 * theta / 25)
    c = np.degrees(theta) + 10.0 * np.sin(theta)
    lines = ["%", "(SYNTHETIC 5-AXIS TCP PROGRAM)", "G21 G90 G17 G40 G94", "T1 M6", "S12000 M3",
             "G43.4 H1", f"G0 A{a[0]:.3f} C{c[0]:.3f}",
             f"G0 X{tip[0, 0]:.4f} Y{tip[0, 1]:.4f} Z{tip[0, 2] + 5:.4f}", "M8", "G93"]
    for k in range(n_blocks):
        if k and k % 500 == 0:
            lines += [f"G0 Z{tip[k - 1, 2] + 5:.4f}", f"G0 A{a[k]:.3f} C{c[k]:.3f}",
                      f"G0 X{tip[k, 0]:.4f} Y{tip[k, 1]:.4f}", f"G1 Z{tip[k, 2]:.4f} F600"]
        lines.append(f"G1 X{tip[k, 0]:.4f} Y{tip[k, 1]:.4f} Z{tip[k, 2]:.4f} "
                     f"A{a[k]:.3f} C{c[k]:.3f} F600")
    lines += ["G94 G1 F600", f"G17 G2 X{tip[-1, 0]:.4f} Y{tip[-1, 1]:.4f} I2 J0 "
              f"Z{tip[-1, 2] - 1:.4f}", "G49", "G0 Z300", "M9", "M5", "M30", "%"]
    path.write_text("\n".join(lines) + "\n")


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("n_blocks", nargs="?", type=int, default=10_000)
    parser.add_argument("--file", type=Path)
    parser.add_argument("--tcp", action="store_true")
    args = parser.parse_args(argv)
    machine = load_machine("zhang2013")
    with tempfile.TemporaryDirectory() as folder:
        path = args.file
        if path is None:
            path = Path(folder) / "synthetic.ngc"
            write_program(path, args.n_blocks)
        before = peak_mb()
        t0 = time.perf_counter()
        program = read_program(path, machine, tcp=args.tcp)
        t1 = time.perf_counter()
        traj = program_trajectory(program, machine)
        t2 = time.perf_counter()
        program_peak = peak_mb()
    n_points = 100_000
    t3 = time.perf_counter()
    baseline = generate_trajectory(synthetic_path(n_points), machine)
    t4 = time.perf_counter()
    base = t4 - t3
    print(f"program {path.name}: {program.n_moves} moves, {traj.n_samples} samples "
          f"({traj.duration:.1f} s of motion)")
    print(f"  read_program        {t1 - t0:7.3f} s   {(t1 - t0) / base:6.3f} x baseline")
    print(f"  program_trajectory  {t2 - t1:7.3f} s   {(t2 - t1) / base:6.3f} x baseline   "
          f"{(t2 - t1) / traj.n_samples * 1e6:.2f} us/sample")
    print(f"  peak resident memory {program_peak:.0f} MB (before reading: {before:.0f} MB)")
    print(f"baseline: generate_trajectory of a {n_points}-point CL path: {base:.3f} s, "
          f"{baseline.n_samples} samples, {base / baseline.n_samples * 1e6:.2f} us/sample")
    print(f"per-sample cost, program / baseline: "
          f"{(t2 - t0) / traj.n_samples / (base / baseline.n_samples):.3f}")


if __name__ == "__main__":
    main(sys.argv[1:])
