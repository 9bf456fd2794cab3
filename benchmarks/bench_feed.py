"""Cost of ``precontour run --tolerance`` in ``run``s: the feed search against a plain run.

The issue's budget: the search (both variants, the baseline and the compensated one, and the
checks on the machine's draws) costs at most 10 plain ``run``s' worth of time. The program
is a G-code or CL file given on the command line, or by default the built-in ``paper`` path
as CL data. Both go through the same code as the commands ``precontour run PROGRAM`` and
``precontour run PROGRAM --tolerance TOL``; the plain run is the baseline of the measurement.

Run: ``python benchmarks/bench_feed.py [PROGRAM] [--machine M] [--controller C]
[--tolerance TIP_UM[,ORI_MRAD]] [--tcp]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from precontour import builtin_path
from precontour.options import ToleranceOptions
from precontour.planning import ContourTolerance
from precontour.workflow import RunOutputs, run_program


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("program", nargs="?", type=Path, default=None)
    parser.add_argument("--machine", default="zhang2013")
    parser.add_argument("--controller", default="pid-low")
    parser.add_argument("--tolerance", default="10", metavar="TIP_UM[,ORI_MRAD]")
    parser.add_argument("--tcp", action="store_true")
    args = parser.parse_args(argv)
    values = [float(v) for v in args.tolerance.split(",")]
    tolerance = ContourTolerance(1e-3 * values[0], 1e-3 * values[1] if len(values) > 1 else None)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        program = args.program
        if program is None:
            path = builtin_path("paper")
            program = folder / "paper.csv"
            np.savetxt(program, np.column_stack([path.P, path.O]), delimiter=",",
                       header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.17g")
        common = dict(machine=args.machine, controller=args.controller, tcp=args.tcp)
        start = time.perf_counter()
        plain = run_program(program, RunOutputs(program=folder / "plain.ngc"), **common)
        plain_time = time.perf_counter() - start
        start = time.perf_counter()
        result = run_program(program, RunOutputs(program=folder / "fast.ngc"),
                             contour_tolerance=ToleranceOptions(tolerance, write_anyway=True),
                             **common)
        search_time = time.perf_counter() - start
    feed = result.feed
    print(f"{program.name}, {args.machine}, {args.controller}, tolerance "
          f"{tolerance.describe()}: {plain.commands.n_samples:,} samples")
    print(f"plain run                 {plain_time:8.1f} s")
    print(f"run --tolerance           {search_time:8.1f} s  = {search_time / plain_time:.1f} runs "
          f"(baseline {feed.baseline.rounds} rounds, {feed.baseline.machine_runs} machine runs; "
          f"compensated {feed.compensated.rounds} rounds, {feed.compensated.machine_runs} "
          "machine runs)")
    print(f"cycle times: as programmed {feed.programmed.duration:,.3f} s, uncompensated "
          f"within tolerance {feed.baseline.duration:,.3f} s"
          + ("" if feed.baseline.met else " (not met)")
          + f", compensated within tolerance {feed.compensated.duration:,.3f} s"
          + ("" if feed.compensated.met else " (not met)")
          + f": {100 * (1 - feed.ratio):.1f} % shorter")


if __name__ == "__main__":
    main()
