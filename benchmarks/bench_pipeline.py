"""Whole-pipeline speed and memory, stage by stage, at 10^4, 10^5 and 10^6 samples.

A synthetic CL path (``bench_trajectory.synthetic_path``: a spiral over a dome with a tilting,
turning tool, about 100 mm/s) is turned into trajectories of the requested sizes. Each stage runs
in its own process (so its peak memory is the whole process's, imports and data included),
after a warm-up on a small trajectory (so compiled code is loaded, not compiled, as on any run
after the first). The baseline, measured in the same run, is ``scipy.signal.lsim`` of the five
closed loops on the same samples. Prints a Markdown table: stage, samples, time, us/sample,
x real time (motion time / compute time), lsim time / stage time, peak memory.

``--long`` adds the 10-hour program: the 2-minute trajectory driven forward, backward,
forward, ... 300 times (3.6e7 samples, a stop at every turn), predicted and compensated piece
by piece (``precontour.compensation.pieces``) without ever holding it in memory.

Run: ``PYTHONPATH=src python benchmarks/bench_pipeline.py [--sizes 1e4,1e5,1e6] [--long]
[--stages "contour errors;compensate, 1 pass"]`` (lsim always runs: it is the baseline). The
same script measures an older version of the package (``PYTHONPATH=old/src``) for comparison.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

CACHE = Path(tempfile.gettempdir()) / "precontour-bench"
STAGES = ("trajectory generation", "fit + predict", "reference curves", "contour errors",
          "compensate, 1 pass", "compensate, --iterations 4",
          "virtual machine (discrete, friction)", "lsim of the 5 loops")
CONTROLLER = "pid-high"
#: CL points per trajectory sample of the synthetic path (measured: 100,000 -> 119,750).
SAMPLES_PER_POINT = 1.1975


def _source_digest() -> str:
    """A digest of the installed package's source and data files."""
    import precontour

    digest = hashlib.sha1()
    root = Path(precontour.__file__).parent
    for file in sorted(root.rglob("*")):
        if file.suffix in (".py", ".toml"):
            digest.update(str(file.relative_to(root)).encode())
            digest.update(file.read_bytes())
    return digest.hexdigest()[:16]


def _trajectory(n_samples: int):
    """The synthetic trajectory with about n_samples samples (cached on disk)."""
    from precontour import load_machine, load_servo
    from precontour.trajectory.generate import generate_trajectory
    from precontour.trajectory.sampled import Trajectory
    from bench_trajectory import synthetic_path

    # One cache per version of the package: the temporary folder is shared, and a trajectory
    # planned by another version (other kinematics) does not match this one's reference.
    folder = CACHE / _source_digest()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"traj_{n_samples}.npz"
    if path.exists():
        data = np.load(path)
        return Trajectory(data["t"], data["q"], data["P"], data["O"])
    traj = generate_trajectory(synthetic_path(int(round(n_samples / SAMPLES_PER_POINT))),
                               load_machine("zhang2013"))
    np.savez(path, t=traj.t, q=traj.q, P=traj.P, O=traj.O)
    return traj


def _stage(name: str, traj):
    """The stage as a function of nothing, on ``traj``."""
    from scipy import signal

    from precontour import load_machine, load_servo
    try:
        from precontour.compensation.pieces import compensate_program
    except ImportError:   # a version from before pieces, measured for comparison
        from precontour.compensation.precompensate import compensate as compensate_program
    from precontour.prediction.contour import ReferencePath
    from precontour.prediction.tracking import predict_tracking
    from precontour.simulation.virtual_machine import simulate_trajectory
    from precontour.trajectory.generate import generate_trajectory
    from bench_trajectory import synthetic_path

    machine = load_machine("zhang2013")
    servo = load_servo(machine, CONTROLLER)
    models = servo.models
    if name == "trajectory generation":
        toolpath = synthetic_path(int(round(traj.n_samples / SAMPLES_PER_POINT)))
        return lambda: generate_trajectory(toolpath, machine)
    if name == "fit + predict":
        return lambda: predict_tracking(traj.t, traj.q, models)(traj.t)
    if name == "reference curves":
        def build():
            reference = ReferencePath.from_trajectory(traj)
            _prepare(reference)
            return reference
        return build
    if name == "contour errors":
        reference = ReferencePath.from_trajectory(traj)
        _prepare(reference)                  # built: the previous stage
        q_act = traj.q - predict_tracking(traj.t, traj.q, models)(traj.t)
        return lambda: reference.errors(*machine.kinematics.forward(q_act))
    if name == "compensate, 1 pass":
        return lambda: compensate_program(servo, traj)
    if name == "compensate, --iterations 4":
        return lambda: compensate_program(servo, traj, iterations=4)
    if name == "virtual machine (discrete, friction)":
        return lambda: simulate_trajectory(traj, machine, CONTROLLER)
    if name == "lsim of the 5 loops":
        return lambda: [signal.lsim((m.num, m.den), traj.q[:, i] - traj.q[0, i], traj.t)
                        for i, m in enumerate(models)]
    raise ValueError(name)


def _prepare(reference) -> None:
    """Build what a reference path computes on first use (whichever version is measured)."""
    for name in ("_tip_arrays", "_orientation_arrays", "_own_windows", "_tip_tree",
                 "_orientation_tree", "_tip_isolation", "_orientation_isolation", "progress"):
        if hasattr(type(reference), name):
            getattr(reference, name)


def _run_stage(name: str, n_samples: int) -> None:
    """In a child process: warm up, run the stage once, print seconds and peak memory."""
    _stage(name, _trajectory(10_000))()
    traj = _trajectory(n_samples)
    fn = _stage(name, traj)
    start = time.perf_counter()
    fn()
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"seconds": seconds, "peak_bytes": peak, "samples": traj.n_samples,
                      "duration": traj.duration}))


def run_child(script: str | Path, *args: str) -> dict:
    """``python script args`` in a fresh process (this environment); the JSON object its
    last line of output prints. The benchmarks that measure stage by stage run each stage
    this way, so that its time and memory are its own."""
    out = subprocess.run([sys.executable, str(script), *args], check=True,
                         capture_output=True, text=True, env=dict(os.environ)).stdout
    return json.loads(out.strip().splitlines()[-1])


def _child(*args: str) -> dict:
    return run_child(__file__, *args)


def _long_program(repeats: int = 300, piece_samples: int | None = None) -> None:
    """In a child process: the 10-hour program, predicted and compensated in pieces."""
    from precontour import load_machine, load_servo
    from precontour.compensation.pieces import PIECE_SAMPLES, compensate_pieces, predict_pieces
    from precontour.trajectory.sampled import Trajectory

    base = _trajectory(120_000)
    length = base.n_samples - 1          # consecutive runs share their turning sample
    n = length * repeats + 1
    ts = base.ts

    def read(start: int, stop: int) -> Trajectory:
        index = np.arange(start, stop)
        run, within = np.divmod(index, length)
        k = np.where(run % 2 == 0, within, length - within)
        return Trajectory(index * ts, base.q[k], base.P[k], base.O[k])

    machine = load_machine("zhang2013")
    servo = load_servo(machine, CONTROLLER)
    pieces = piece_samples or PIECE_SAMPLES
    result = {"samples": n, "duration": n * ts}

    def report(stage, piece, start):
        # progress on stderr: samples done, seconds, peak memory so far
        print(f"{stage}: {piece.keep_stop:,} of {n:,} samples in "
              f"{time.perf_counter() - start:.1f} s, peak "
              f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB",
              file=sys.stderr, flush=True)
    start = time.perf_counter()
    before = after = 0.0
    for piece, part in compensate_pieces(servo, read, n, ts,
                                         piece_samples=pieces):
        before = max(before, float(part.before.tip.max()))
        after = max(after, float(part.after.tip.max()))
        report("compensate", piece, start)
    result["compensate_seconds"] = time.perf_counter() - start
    result["compensate_tip_max_um"] = (1e3 * before, 1e3 * after)
    start = time.perf_counter()
    worst = 0.0
    for piece, _, contour, _ in predict_pieces(servo, read, n, ts,
                                               piece_samples=pieces):
        worst = max(worst, float(contour.tip.max()))
        report("predict", piece, start)
    result["predict_seconds"] = time.perf_counter() - start
    result["predict_tip_max_um"] = 1e3 * worst
    result["peak_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps(result))


def main(argv: list[str]) -> None:
    if argv and argv[0] == "--stage":
        _run_stage(argv[1], int(argv[2]))
        return
    if argv and argv[0] == "--long-child":
        _long_program(int(argv[1]))
        return
    if argv and argv[0] == "--plan":
        _trajectory(int(argv[1]))
        print(json.dumps({}))
        return
    sizes = [10_000, 100_000, 1_000_000]
    if "--sizes" in argv:
        sizes = [int(float(s)) for s in argv[argv.index("--sizes") + 1].split(",")]
    stages = STAGES
    if "--stages" in argv:
        wanted = argv[argv.index("--stages") + 1].split(";")
        stages = tuple(name for name in STAGES if name in wanted or name == STAGES[-1])
    print("| stage | samples | time (s) | us / sample | x real time | lsim / stage | "
          "peak memory (MB) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    lsim_us = None
    for n in sizes:
        # planned in a child: Linux keeps a process's peak memory across fork and exec, so a
        # trajectory planned here would show as every stage's peak memory
        _child("--plan", str(n))
        results = {name: _child("--stage", name, str(n)) for name in stages}
        lsim = results["lsim of the 5 loops"]["seconds"]
        samples = results["lsim of the 5 loops"]["samples"]
        lsim_us = 1e6 * lsim / samples
        for name in stages:
            r = results[name]
            print(f"| {name} | {r['samples']:,} | {r['seconds']:.3g} | "
                  f"{1e6 * r['seconds'] / r['samples']:.3g} | {r['duration'] / r['seconds']:.0f} | "
                  f"{lsim / r['seconds']:.2g} | {r['peak_bytes'] / 2**20:.0f} |", flush=True)
    if "--long" in argv:
        r = _child("--long-child", "300")
        for stage in ("predict", "compensate"):
            seconds = r[f"{stage}_seconds"]
            ratio = f"{lsim_us * r['samples'] / 1e6 / seconds:.2g}" if lsim_us else "-"
            print(f"| 10-hour program, {stage} in pieces | {r['samples']:,} | {seconds:.4g} | "
                  f"{1e6 * seconds / r['samples']:.3g} | {r['duration'] / seconds:.0f} | "
                  f"{ratio} | {r['peak_bytes'] / 2**20:.0f} (both) |", flush=True)
        print(f"(10-hour program: predicted tip max {r['predict_tip_max_um']:.2f} um; compensated "
              f"{r['compensate_tip_max_um'][0]:.2f} -> {r['compensate_tip_max_um'][1]:.3f} um; "
              f"lsim / stage from lsim's us/sample at the largest size)")


if __name__ == "__main__":
    main(sys.argv[1:])
