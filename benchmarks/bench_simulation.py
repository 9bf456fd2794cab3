"""Speed and memory of the virtual machine against ``scipy.signal.lsim`` of the five loops.

A five-axis command of N samples at the 1 ms servo period (rest-to-rest moves with reversals
and dwells, repeated with varying amplitudes) runs on the realistic machine (discrete PID at
1 kHz with zero-order hold, Stribeck friction with stick-slip, friction feed-forward) and in
the continuous mode, each in a fresh process so that its peak resident memory is its own.
The baseline, measured in the same run, is ``scipy.signal.lsim`` of the five closed loops'
e(s)/X(s) on the same command. Prints time, microseconds per sample, times real time, the
ratio of lsim's time to the simulation's, and peak memory, at 10^4, 10^5 and 10^6 samples.
Run: ``python benchmarks/bench_simulation.py [N ...]``.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

import numpy as np

CONTROLLER = "pid-high"
MODES = ("discrete", "continuous")


def command(n: int, ts: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """N samples of repeated rest-to-rest moves (2 s moving, 0.5 s dwell) with reversals."""
    t = np.arange(n) * ts
    cycle = np.floor(t / 2.5)
    tau = np.clip((t - 2.5 * cycle) / 2.0, 0.0, 1.0)
    s = tau**4 * (35 - 84 * tau + 70 * tau**2 - 20 * tau**3)
    amp = 1.0 + 0.5 * np.sin(0.7 * cycle)
    q = np.column_stack([40 * amp * np.sin(np.pi * s), 30 * np.sin(2 * np.pi * s),
                         -10 * amp * (1 - np.cos(2 * np.pi * s)), 0.8 * amp * np.sin(np.pi * s),
                         1.0 * np.sin(2 * np.pi * s)])
    return t, q


def run_one(kind: str, n: int) -> dict:
    """Time one run in this process; 'lsim' or a simulation mode."""
    from precontour import load_machine
    from precontour.simulation.virtual_machine import simulate

    machine = load_machine("zhang2013")
    t, q = command(n, machine.servo_period)
    if kind == "lsim":
        from scipy import signal
        models = machine.error_models(CONTROLLER)
        start = time.perf_counter()
        for i, m in enumerate(models):
            signal.lsim((m.num, m.den), q[:, i] - q[0, i], t)
    else:
        # Compile (or load the cached compilation) outside the timed run.
        simulate(t[:200], q[:200], machine, CONTROLLER, mode=kind)
        start = time.perf_counter()
        simulate(t, q, machine, CONTROLLER, mode=kind)
    seconds = time.perf_counter() - start
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return dict(seconds=seconds, peak_mb=peak_mb)


def measure(kind: str, n: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--one", kind, str(n)], check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(sizes: list[int]) -> None:
    print(f"controller {CONTROLLER}; each run in a fresh process; memory = its peak RSS")
    print(f"{'N':>9} {'stage':<22} {'time s':>9} {'us/sample':>10} {'x real time':>12} "
          f"{'lsim / this':>12} {'peak MB':>9}")
    for n in sizes:
        lsim = measure("lsim", n)
        rows = [("lsim (baseline)", lsim)] + [(f"virtual machine {m}", measure(m, n))
                                             for m in MODES]
        for label, r in rows:
            sec = r["seconds"]
            print(f"{n:>9} {label:<22} {sec:9.3f} {1e6 * sec / n:10.2f} "
                  f"{n * 1e-3 / sec:12.0f} {lsim['seconds'] / sec:12.2f} {r['peak_mb']:9.0f}",
                  flush=True)


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        print(json.dumps(run_one(sys.argv[2], int(sys.argv[3]))))
    else:
        main([int(a) for a in sys.argv[1:]] or [10_000, 100_000, 1_000_000])
