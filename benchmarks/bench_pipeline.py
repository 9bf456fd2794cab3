"""Whole-pipeline speed on a long realistic trajectory, stage by stage.

A synthetic CL path of N points (default 100,000, about 2 minutes of motion at 100 mm/s) is
turned into a trajectory, predicted, measured for contour errors, pre-compensated (one pass)
and simulated on the virtual machine. Prints each stage's time and microseconds per sample,
and, as the baseline measured in the same run, ``scipy.signal.lsim`` of the five closed loops.
Run: ``python benchmarks/bench_pipeline.py [N_POINTS]``.
"""

from __future__ import annotations

import sys
import time

from scipy import signal

from precontour import load_machine
from precontour.compensation.precompensate import compensate
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.virtual_machine import simulate_trajectory
from precontour.prediction.tracking import predict_tracking
from precontour.trajectory.generate import generate_trajectory

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_trajectory import synthetic_path  # noqa: E402


def timed(label, fn, n):
    start = time.perf_counter()
    out = fn()
    seconds = time.perf_counter() - start
    print(f"  {label:<34} {seconds:8.3f} s {1e6 * seconds / n:8.2f} us/sample", flush=True)
    return out, seconds


def main(n_points: int = 100_000) -> None:
    machine = load_machine("zhang2013")
    models = machine.controller("pid-high").error_models(machine.drives)
    toolpath = synthetic_path(n_points)
    traj = generate_trajectory(toolpath, machine)
    n = traj.n_samples
    print(f"{n_points} CL points -> {n} samples ({traj.duration:.1f} s of motion)")
    prediction, t_pred = timed("fit + predict", lambda: predict_tracking(traj.t, traj.q, models), n)
    e, _ = timed("evaluate e at every sample", lambda: prediction(traj.t), n)
    reference, _ = timed("reference curves", lambda: ReferencePath.from_trajectory(traj), n)
    timed("contour errors (predicted)",
          lambda: contour_errors(reference, traj.q - e, machine.kinematics), n)
    timed("compensate (1 pass)",
          lambda: compensate(traj, machine.kinematics, models, reference=reference), n)
    timed("virtual machine (discrete, friction)",
          lambda: simulate_trajectory(traj, machine, "pid-high"), n)
    _, t_lsim = timed("baseline: lsim of the 5 loops", lambda: [
        signal.lsim((m.num, m.den), traj.q[:, i] - traj.q[0, i], traj.t)
        for i, m in enumerate(models)], n)
    print(f"  lsim / (fit + predict) = {t_lsim / t_pred:.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
