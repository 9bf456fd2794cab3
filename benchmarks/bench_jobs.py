"""What a second core buys: each stage with independent work at one job and at two.

The stages that spread independent work (``precontour.parallel``): the virtual machine (its
five axes), the fit and prediction (five axes), the contour errors (the chunks of the
closest-point search), one compensation pass, the check of both commands on five draws of the
machine ensemble (draws on threads), and a batch of four programs (programs in processes).
Each stage runs in its own process, once at ``--jobs 1`` and once at ``--jobs 2``, after a
warm-up, the fastest of three runs, on the synthetic trajectory of ``bench_pipeline.py`` (default 2 * 10^5 samples).
The baseline is the same stage at one job in the same run; the table gives the speed-up
(one job's time over two jobs'), the issue's target being 1.7 on two cores.

Run: ``python benchmarks/bench_jobs.py [--samples 2e5] [--stages "draw check;batch"]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

STAGES = ("virtual machine (5 axes)", "fit + predict (5 axes)", "contour errors (chunks)",
          "compensate, 1 pass", "draw check (5 draws)", "batch (4 programs)")
CONTROLLER = "pid-high"
#: Runs of each stage in its process; the fastest counts (the machine is shared).
REPEATS = 3
PROGRAM = HERE.parent / "tests" / "linuxcnc" / "data" / "3plus2.ngc"


def _stage(name: str, traj, folder: Path):
    """The stage as a function of nothing, on ``traj``."""
    from bench_pipeline import _prepare
    from precontour import load_machine, load_servo
    from precontour.compensation.pieces import compensate_program, contour_errors_program
    from precontour.prediction.contour import ReferencePath
    from precontour.prediction.tracking import predict_tracking
    from precontour.simulation.ensemble import MachineEnsemble
    from precontour.simulation.virtual_machine import simulate_trajectory
    from precontour.workflow import check_on_draws

    machine = load_machine("zhang2013")
    servo = load_servo(machine, CONTROLLER)
    models = servo.models
    if name == "virtual machine (5 axes)":
        return lambda: simulate_trajectory(traj, machine, CONTROLLER)
    if name == "fit + predict (5 axes)":
        return lambda: predict_tracking(traj.t, traj.q, models)(traj.t)
    if name == "contour errors (chunks)":
        reference = ReferencePath.from_trajectory(traj)
        _prepare(reference)
        q_act = traj.q - predict_tracking(traj.t, traj.q, models)(traj.t)
        return lambda: reference.errors(*machine.kinematics.forward(q_act))
    if name == "compensate, 1 pass":
        return lambda: compensate_program(servo, traj)
    if name == "draw check (5 draws)":
        compensated = compensate_program(servo, traj).trajectory.q
        nominal = tuple(contour_errors_program(traj, q, machine.kinematics)
                        for q in (traj.q, compensated))
        return lambda: check_on_draws(traj, compensated, machine, CONTROLLER, nominal,
                                      ensemble=MachineEnsemble(draws=5))
    if name == "batch (4 programs)":
        from precontour.batch import run_batch
        from precontour.parallel import jobs

        programs = folder / "programs"
        programs.mkdir(exist_ok=True)
        for k in range(4):
            (programs / f"p{k}.ngc").write_text(
                PROGRAM.read_text().replace("F2400", f"F{2000 + 200 * k}"))
        counter = iter(range(1000))
        return lambda: run_batch([programs], folder / f"out{next(counter)}",
                                 machines=["zhang2013"], controller=CONTROLLER, jobs=jobs())
    raise ValueError(name)


def _run_stage(name: str, n_samples: int, jobs: int) -> None:
    """In a child process: warm up, run the stage :data:`REPEATS` times at ``jobs``, print
    the fastest run's seconds."""
    from bench_pipeline import _trajectory
    from precontour.parallel import using_jobs

    with tempfile.TemporaryDirectory() as folder, using_jobs(jobs):
        _stage(name, _trajectory(10_000), Path(folder))()
        fn = _stage(name, _trajectory(n_samples), Path(folder))
        seconds = []
        for _ in range(REPEATS):
            start = time.perf_counter()
            fn()
            seconds.append(time.perf_counter() - start)
        print(json.dumps({"seconds": min(seconds)}))


def _child(*args: str) -> dict:
    from bench_pipeline import run_child

    return run_child(__file__, *args)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=2e5)
    parser.add_argument("--stages", default=";".join(STAGES))
    parser.add_argument("--child", nargs=3, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        name, n, jobs = args.child
        _run_stage(name, int(float(n)), int(jobs))
        return
    n = int(args.samples)
    print(f"samples {n:,}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.2f} at the start\n")
    print("| stage | --jobs 1 | --jobs 2 | speed-up |")
    print("|---|---|---|---|")
    for name in args.stages.split(";"):
        one = _child("--child", name, str(n), "1")["seconds"]
        two = _child("--child", name, str(n), "2")["seconds"]
        print(f"| {name} | {one:.2f} s | {two:.2f} s | {one / two:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
