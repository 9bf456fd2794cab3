"""Speed and timing of reading back a program that ``run`` or ``export`` writes (a script, not
a test).

The program is the G-code writer's output (``gcode_program``: G93 blocks decimated within
1 um / 1e-5 rad, as ``run`` and ``export`` write) of a planned trajectory of the synthetic
five-axis CL path of ``bench_trajectory.py`` (N points). It times, in the same run:

- reading the program (``read_program``) and planning it (``program_trajectory``, dwell 0),
  per 10,000 blocks, and the planned duration against the program's own 60/F (the issue's
  target: within 1 %, under 5 s per 10,000 blocks);
- the baseline: planning the CL path itself (``generate_trajectory``), and prints the ratio.

    PYTHONPATH=src python benchmarks/bench_readback.py [N_POINTS]   (default 20,000)
    PYTHONPATH=src python benchmarks/bench_readback.py --file OUT.ngc --machine NAME

Measured (2-core machine, shared): LinuxCNC's boats through ``run`` (linuxcnc-xyzac-trt /
-xyzbc-trt, pid-high): A-C 13,746 blocks, 594.43 s of 60/F, planned 603.55 s (+1.5 %) in
2.7 s; B-C 10,687 blocks, 409.41 s, planned 414.47 s (+1.2 %) in 1.7 s. The default
synthetic case (11,656 blocks, 24.24 s of 60/F): planned 30.79 s (+27 %) in 0.60 s, 1.9 x
baseline; before the limits were kept by re-timing, 485.07 s (+1901 %) in 21.0 s, 82.5 x. What
is left of the +27 %: corners that the filters would blend beyond the program's G64 P0.001
become stops.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from precontour import load_machine
from precontour.toolpath import read_program
from precontour.toolpath.writers import gcode_program
from precontour.trajectory import generate_trajectory, program_trajectory

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_trajectory import synthetic_path  # noqa: E402


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("n_points", nargs="?", type=int, default=20_000)
    parser.add_argument("--file", type=Path)
    parser.add_argument("--machine", default="zhang2013")
    args = parser.parse_args(argv)
    machine = load_machine(args.machine)
    t0 = time.perf_counter()
    planned = generate_trajectory(synthetic_path(args.n_points), machine)
    base = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as folder:
        path = args.file
        if path is None:
            path = Path(folder) / "written.ngc"
            path.write_text(gcode_program(planned.t, planned.q,
                                          axis_names=machine.axis_names).text)
        t1 = time.perf_counter()
        program = read_program(path, machine)
        t2 = time.perf_counter()
        traj = program_trajectory(program, machine, dwell=0.0)
        t3 = time.perf_counter()
    own = float(np.nansum(program.duration))
    per = 10_000 / program.n_moves
    print(f"program {path.name}: {program.n_moves} blocks, 60/F {own:.3f} s, planned "
          f"{traj.duration:.3f} s ({100 * (traj.duration / own - 1):+.2f} %)")
    print(f"  read_program        {t2 - t1:7.3f} s   {(t2 - t1) * per:6.2f} s per 10,000 blocks")
    print(f"  program_trajectory  {t3 - t2:7.3f} s   {(t3 - t2) * per:6.2f} s per 10,000 blocks"
          f"   {(t3 - t2) / base:6.3f} x baseline")
    print(f"baseline: generate_trajectory of the {args.n_points}-point CL path: {base:.3f} s, "
          f"{planned.n_samples} samples")


if __name__ == "__main__":
    main(sys.argv[1:])
