"""The demonstration: the paper's evaluation (spec section 7) re-run on the virtual machine.

For each built-in path and each controller: generate the trajectory, predict the axis tracking
errors in closed form, pre-compensate the contour errors, and run both the uncompensated and
the pre-compensated commands on two machines -- the realistic one (discrete controllers at the
servo period, friction, feed-forward friction compensation) and the exact linear model
(continuous controllers, no friction) -- measuring the contour errors against the reference.
This module owns the orchestration and its result objects; :mod:`precontour.reports.demo_report` draws and
writes them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from ..trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
from ..compensation.precompensate import CompensationResult, compensate
from ..compensation.programmed_end import required_final_rest, with_final_rest
from ..prediction.contour import ContourErrors, ReferencePath, contour_errors
from ..errors import InputError, is_whole_number, plain
from ..files import check_report_folder, input_files
from ..machine.machine_file import Machine, load_machine
from ..machine.servo import load_servo
from ..simulation.virtual_machine import REALISTIC, SimulationResult, simulate_trajectory
from ..machine.controllers import closed_loop_bandwidth
from ..prediction.tracking import AxisPrediction, predict_tracking
from ..trajectory.sampled import Trajectory
from ..trajectory.generate import TrajectorySummary, generate_trajectory, summarize
from .progress import Progress, StepCounter

#: The two virtual machines every command runs on: name -> simulate() options.
MACHINE_MODELS: dict[str, dict] = {
    "realistic": REALISTIC,
    "exact": dict(mode="continuous", friction=False, ff_friction=False),
}
#: Trajectory kinds, in table order.
TRAJECTORY_KINDS: tuple[str, ...] = ("uncompensated", "pre-compensated")

@dataclass(frozen=True)
class MachineRun:
    """One command run on one virtual machine: the simulated motion and its contour errors
    against the reference path."""

    simulation: SimulationResult
    contour: ContourErrors


@dataclass(frozen=True)
class CaseResult:
    """One path under one controller.

    Attributes
    ----------
    path, controller : str
        Built-in path and controller names.
    trajectory : Trajectory
        The reference commands (with the reference tool path P, O).
    prediction : AxisPrediction
        Closed-form tracking errors of the uncompensated commands (``prediction(t)``, (N, 5)).
    compensation : CompensationResult
        Pre-compensated commands and the predicted contour errors before and after.
    runs : mapping (machine model, trajectory kind) -> MachineRun
        Keys ``("realistic" | "exact", "uncompensated" | "pre-compensated")``.
    """

    path: str
    controller: str
    trajectory: Trajectory
    prediction: AxisPrediction
    compensation: CompensationResult
    runs: Mapping[tuple[str, str], MachineRun]

    def run(self, model: str, kind: str) -> MachineRun:
        """The run of trajectory ``kind`` on machine ``model`` (see :data:`MACHINE_MODELS`)."""
        return self.runs[(model, kind)]


@dataclass(frozen=True)
class DemoResult:
    """Everything :func:`run_demo` computed and wrote.

    Attributes
    ----------
    out_dir : Path
        The report folder.
    machine : Machine
    paths, controllers : tuple of str
    iterations : int
        Largest number of compensation passes asked for.
    summaries : mapping path -> TrajectorySummary
    bandwidths : mapping controller -> ndarray, shape (5,)
        Closed-loop -3 dB bandwidth of each axis's linear model, Hz.
    cases : tuple of CaseResult
        In path-major, controller-minor order.
    rows : list of dict
        The Tables 3/4-style table (see :func:`precontour.reports.demo_report.table_rows`).
    files : tuple of Path
        Every file written, ``index.html`` last.
    timings : dict
        Wall time (s) per stage: ``"compute"``, ``"report"``, ``"total"``.
    """

    out_dir: Path
    machine: Machine
    paths: tuple[str, ...]
    controllers: tuple[str, ...]
    iterations: int
    summaries: Mapping[str, TrajectorySummary]
    bandwidths: Mapping[str, np.ndarray]
    cases: tuple[CaseResult, ...]
    rows: list = field(default_factory=list)
    files: tuple[Path, ...] = ()
    timings: dict = field(default_factory=dict)

    def case(self, path: str, controller: str) -> CaseResult:
        for case in self.cases:
            if case.path == path and case.controller == controller:
                return case
        raise KeyError((path, controller))


def demo_file_names(paths, controllers) -> dict[str, str]:
    """Names of the files a demo writes, keyed by role: ``table.csv``, ``table.md``,
    ``path:<p>``, ``tracking:<p>:<c>``, ``contour:<p>:<c>`` and ``index.html``."""
    controllers = tuple(controllers)
    names = {"table.csv": "contour_errors.csv", "table.md": "contour_errors.md"}
    for p in paths:
        names[f"path:{p}"] = f"path_{p}.png"
        for c in controllers:
            names[f"contour:{p}:{c}"] = f"contour_{p}_{c}.png"
            names[f"tracking:{p}:{c}"] = f"tracking_{p}_{c}.png"
    names["index.html"] = "index.html"
    return names


def compute_demo(out_dir: str | Path, *, paths: tuple[str, ...] = ("paper",),
             controllers: tuple[str, ...] = ("pid-high", "pid-low"), iterations: int = 1,
             machine: str | Path | Machine = "zhang2013",
             progress: Progress | None = None) -> DemoResult:
    """Run the paper's evaluation on the virtual machine (the report is written by
    :func:`precontour.reports.demo_report.run_demo`).

    Parameters
    ----------
    out_dir : str or Path
        Report folder; created if missing. Only the files the report writes are overwritten;
        nothing is deleted.
    paths : tuple of str
        Built-in paths (:data:`precontour.trajectory.builtin_paths.BUILTIN_PATHS`).
    controllers : tuple of str
        Controller names of ``machine`` (linear controllers: they are predicted in closed form).
    iterations : int
        Largest number of contour pre-compensation passes (1 = the paper's single pass).
    machine : str, Path or Machine
        Built-in machine name, machine file, or a loaded machine.
    progress : callable, optional
        ``progress(done, total, message)`` before each step, e.g. :class:`ProgressLine`.

    Returns
    -------
    DemoResult
        The result, without report files (:func:`~precontour.reports.demo_report.run_demo`
        writes them, as its own step of ``progress``).
    """
    paths, controllers = _check_names(paths, controllers, iterations)
    machine_file = machine
    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    servos = {name: load_servo(machine, name) for name in controllers}
    out_dir = check_report_folder(
        out_dir, demo_file_names(paths, controllers).values(),
        inputs=[] if isinstance(machine_file, Machine) else input_files(machine_file),
        what="demo")

    runs_per_case = len(MACHINE_MODELS) * len(TRAJECTORY_KINDS)
    total = len(paths) * (1 + len(controllers) * (1 + runs_per_case))
    step = StepCounter(progress, total)

    start = time.perf_counter()
    summaries, cases = {}, []
    for path in paths:
        step(f"{path}: trajectory")
        # with the final rest the slowest compensated loop needs to end at the programmed end
        # point (both controllers judged on the same plan)
        traj = with_final_rest(generate_trajectory(builtin_path(path), machine,
                                                   ts=machine.servo_period),
                               max(required_final_rest(servos[name].models)
                                   for name in controllers))
        summaries[path] = summarize(traj, machine)
        reference = ReferencePath.from_trajectory(traj)
        for name in controllers:
            step(f"{path} {name}: predict and pre-compensate")
            prediction = predict_tracking(traj.t, traj.q, servos[name].models)
            comp = compensate(servos[name], traj, method="contour",
                              iterations=iterations, reference=reference)
            commands = {"uncompensated": traj, "pre-compensated": comp.trajectory}
            runs = {}
            for model, options in MACHINE_MODELS.items():
                for kind in TRAJECTORY_KINDS:
                    step(f"{path} {name}: {kind} on the {model} machine")
                    sim = simulate_trajectory(commands[kind], machine, name, **options)
                    runs[(model, kind)] = MachineRun(
                        simulation=sim,
                        contour=contour_errors(reference, sim.q_act, machine.kinematics))
            cases.append(CaseResult(path=path, controller=name, trajectory=traj,
                                    prediction=prediction, compensation=comp, runs=runs))
    computed = time.perf_counter()
    bandwidths = {name: np.array([closed_loop_bandwidth(m) for m in servos[name].models])
                  for name in controllers}
    timings = {"compute": computed - start}
    result = DemoResult(out_dir=out_dir, machine=machine, paths=paths, controllers=controllers,
                        iterations=iterations, summaries=summaries, bandwidths=bandwidths,
                        cases=tuple(cases), timings=timings)
    return result


def _check_names(paths, controllers, iterations) -> tuple[tuple[str, ...], tuple[str, ...]]:
    paths = tuple(paths)
    controllers = tuple(controllers)
    if not paths:
        raise InputError("no path to run: give at least one of " + ", ".join(BUILTIN_PATHS),
                         field="paths")
    for name in paths:
        if name not in BUILTIN_PATHS:
            raise InputError(f"unknown built-in path {name!r}; choose from "
                             f"{', '.join(BUILTIN_PATHS)}", field="paths")
    if len(set(paths)) != len(paths):
        raise InputError(f"a path is named twice: {', '.join(paths)}", field="paths")
    if not controllers:
        raise InputError("no controller to run", field="controllers")
    if len(set(controllers)) != len(controllers):
        raise InputError(f"a controller is named twice: {', '.join(controllers)}",
                         field="controllers")
    if not is_whole_number(iterations) or iterations < 1:
        raise InputError(f"iterations must be a whole number >= 1, got {plain(iterations)!r}",
                         field="iterations")
    return paths, controllers
