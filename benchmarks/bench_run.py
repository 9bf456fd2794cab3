"""Speed of ``precontour run`` on a long program, stage by stage.

The program is a synthetic five-axis CL path (the spiral of ``bench_trajectory.py``, tool
tilting and turning) written as a CL-data CSV and sized to last ``MINUTES`` minutes of motion
(default 18, about 10^6 samples at 1 kHz). It goes through the same code as the command
``precontour run PATH -o OUT.ngc --stream OUT.txt --commands OUT.csv``: read and plan,
compensate within the machine's limits (re-timing rounds included), the virtual machine on
the uncompensated and the compensated commands, G-code, halstreamer and command files.
The baseline, measured in the same run, is reading and planning alone (the ``trajectory``
command); each stage's time is also given as a multiple of it.

Run: ``python benchmarks/bench_run.py [MINUTES] [CONTROLLER]``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from precontour.workflow import RunOutputs, run_program, write_run_outputs

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_trajectory import synthetic_path  # noqa: E402

#: Seconds of motion per point of the synthetic path (measured: 100,000 points -> 119.75 s).
SECONDS_PER_POINT = 119.75 / 100_000


def main(minutes: float = 18.0, controller: str = "pid-high") -> None:
    n_points = int(round(minutes * 60.0 / SECONDS_PER_POINT))
    toolpath = synthetic_path(n_points)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        program = folder / "long.csv"
        np.savetxt(program, np.column_stack([toolpath.P, toolpath.O]), delimiter=",",
                   header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.9f")
        outputs = RunOutputs(program=folder / "out.ngc", stream=folder / "out.txt",
                             commands=folder / "out.csv")

        from precontour.machine.machine_file import load_machine
        from precontour.workflow import load_program_trajectory
        start = time.perf_counter()
        load_program_trajectory(program, load_machine("zhang2013"))
        baseline = time.perf_counter() - start

        def progress(done, total, message):
            print(f"  [{time.perf_counter() - start:7.1f} s] {message}", flush=True)

        start = time.perf_counter()
        result = run_program(program, outputs, machine="zhang2013", controller=controller,
                             progress=progress, workers=None)
        computed = time.perf_counter() - start
        write_start = time.perf_counter()
        write_run_outputs(result, outputs, [program])
        written = time.perf_counter() - write_start
        sizes = {p.name: p.stat().st_size / 1e6 for p in outputs.files()}
    total = computed + written
    n = result.commands.n_samples
    print(f"{n_points} CL points, {result.planned.duration / 60:.2f} min planned, "
          f"{n} samples after {result.limited.rounds} compensation round(s) "
          f"(+{result.limited.added_time:.3f} s slowed), {result.program.n_blocks} blocks, "
          f"controller {controller}")
    print(f"  {'stage':<32}{'s':>9}{'x plan':>9}{'us/sample':>11}")
    rows = list(result.timings.items()) + [("write files", written), ("total run", total)]
    print(f"  {'baseline: read + plan alone':<32}{baseline:9.2f}{1.0:9.2f}"
          f"{1e6 * baseline / n:11.2f}")
    for name, seconds in rows:
        print(f"  {name:<32}{seconds:9.2f}{seconds / baseline:9.2f}{1e6 * seconds / n:11.2f}")
    print("  files (MB): " + ", ".join(f"{k} {v:.1f}" for k, v in sizes.items()))
    print(result.table())


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 18.0,
         sys.argv[2] if len(sys.argv) > 2 else "pid-high")
