"""Start-up time of the command line (a script, not a test): wall time of a fresh
``python -m precontour ...`` process for the commands that need no computing (help, version,
the list of machines), best and median of REPEATS runs, next to a bare ``python -c pass`` and
to importing what a computing command loads (``precontour.workflow``: numpy, scipy, numba,
the compiled kernels from their cache).

    PYTHONPATH=src python benchmarks/bench_startup.py [REPEATS]

tests/test_cli.py checks that these commands import no numerical library; this script says how
long they take on the machine at hand (the target is 0.3 s).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time

CASES = (
    ("python -c pass", ["-c", "pass"]),
    ("precontour --help", ["-m", "precontour", "--help"]),
    ("precontour --version", ["-m", "precontour", "--version"]),
    ("precontour run --help", ["-m", "precontour", "run", "--help"]),
    ("precontour machines", ["-m", "precontour", "machines"]),
    ("import precontour.workflow", ["-c", "import precontour.workflow"]),
)


def wall_times(argv: list[str], repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, *argv], check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return times


def main(repeats: int = 5) -> None:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{os.cpu_count()} CPU(s), load average {load:.2f}; {repeats} runs each")
    print(f"  {'command':<28}{'best s':>9}{'median s':>10}")
    for label, argv in CASES:
        wall_times(argv, 1)  # warm the file cache and the bytecode
        times = wall_times(argv, repeats)
        print(f"  {label:<28}{min(times):9.3f}{statistics.median(times):10.3f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
