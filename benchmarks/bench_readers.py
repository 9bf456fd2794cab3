"""Read speed of the tool-path readers on 100,000-point files (a script, not a test).

Writes a CL CSV, an APT file and a G-code program of N points (CAM-like precision: 4
decimals for lengths, 7 for orientations, 3 for angles) to a temporary folder, reads each
a few times and prints the best wall time.

    PYTHONPATH=src python benchmarks/bench_readers.py [N]
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_apt, read_clcsv, read_gcode


def make_path(n: int):
    s = np.linspace(0.0, 1.0, n)
    P = np.column_stack([100 * s, 30 * np.sin(20 * s), 10 * np.cos(5 * s)])
    tilt = np.radians(30) * np.sin(7 * s)
    turn = 6 * s
    O = np.column_stack([np.sin(tilt) * np.sin(turn), np.sin(tilt) * np.cos(turn), np.cos(tilt)])
    feed = 1000 + 500 * np.sin(3 * s)
    q = np.column_stack([P, np.degrees(tilt), np.degrees(turn)])
    return P, O, feed, q


def write_files(folder: Path, n: int):
    P, O, feed, q = make_path(n)
    csv = folder / "path.csv"
    np.savetxt(csv, np.column_stack([P, O, feed]), delimiter=",",
               fmt=["%.4f"] * 3 + ["%.7f"] * 3 + ["%.1f"],
               header="Px,Py,Pz,Oi,Oj,Ok,F", comments="")
    apt = folder / "path.apt"
    lines = ["PARTNO BENCH", "MULTAX", "UNITS/MM", "FEDRAT/MMPM,1000.0"]
    lines += ["GOTO/%.4f,%.4f,%.4f,%.7f,%.7f,%.7f" % tuple(row) for row in np.column_stack([P, O])]
    lines.append("FINI")
    apt.write_text("\n".join(lines) + "\n")
    nc = folder / "path.nc"
    lines = ["%", "O0001", "G90 G21 G94", "G0 X0 Y0 Z50 A0 C0"]
    lines += ["N%d G1 X%.4f Y%.4f Z%.4f A%.3f C%.3f F%.0f" % (10 * k, *row)
              for k, row in enumerate(np.column_stack([q, feed]))]
    lines += ["M30", "%"]
    nc.write_text("\n".join(lines) + "\n")
    return csv, apt, nc


def best_time(func, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        times.append(time.perf_counter() - t0)
    return min(times)


def main(n: int = 100_000) -> None:
    machine = load_machine("zhang2013")
    warnings.simplefilter("ignore", UserWarning)  # 7-digit orientations get normalized
    with tempfile.TemporaryDirectory() as tmp:
        csv, apt, nc = write_files(Path(tmp), n)
        for name, path, func in [
            ("CL CSV", csv, lambda: read_clcsv(csv)),
            ("APT", apt, lambda: read_apt(apt)),
            ("G-code", nc, lambda: read_gcode(nc, machine)),
        ]:
            seconds = best_time(func)
            size = path.stat().st_size / 1e6
            print(f"{name:7s} {n:>9,d} points  {size:6.1f} MB  {seconds * 1e3:8.1f} ms  "
                  f"({n / seconds / 1e6:.2f} M points/s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
