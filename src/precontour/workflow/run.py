"""The ``run`` workflow: program in, checked, compensated program out (:func:`run_program`):
plan, compensate within the machine's limits (the route
:func:`precontour.compensation.compensate` takes by default), optionally learn against the
realistic virtual machine (:func:`~precontour.compensation.routes.learn_on_ensemble`) or
search the fastest feed within a contour tolerance, and check both commands on the virtual
machine and its draws."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..compensation.programmed_end import required_final_rest, with_final_rest
from ..compensation.routes import can_learn, learn_on_ensemble
from ..compensation.within_limits import LimitedCompensation, compensate_within_limits
from ..defaults import (DEFAULT_CHECK_DRAWS, DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                        DEFAULT_CORNER_TOLERANCE, DEFAULT_DWELL)
from ..errors import (InputError, ToleranceError, is_whole_number, renamed_keyword, warning,
                      with_former_spellings)
from ..files import check_signals
from ..machine.servo import Servo, load_servo
from ..options import (LearningOptions, LimitOptions, ToleranceOptions, learning_options,
                       limit_options)
from ..planning.tolerance import ContourTolerance, FeedWithinTolerance, feed_within_tolerance
from ..simulation.ensemble import MachineEnsemble
from ..toolpath.writers import ProgramInfo, gcode_program, gcode_tolerances
from .checks import check_on_draws, check_on_virtual_machine, worse_in_whole_message
from .program import RunProgram, plan_run_program, read_run_program
from .result import RunOutputs, RunResult, check_run_outputs


Progress = Callable[[int, int, str], None]


def run_program(program: str | Path, outputs: RunOutputs | None = None, *, machine: str | Path,
                controller: str, tcp: bool = False, dwell: float = DEFAULT_DWELL,
                corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                corner_orientation_tolerance: float | None =
                DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                max_samples: int | None = None, iterations: int = 1,
                gcode_tolerance: np.ndarray | None = None, progress: Progress | None = None,
                workers: int | None = 1, learn: int | LearningOptions = 0,
                ensemble: MachineEnsemble | None = None,
                limits: LimitOptions = LimitOptions(),
                contour_tolerance: ToleranceOptions | ContourTolerance | None = None,
                min_speed: float | None = None, feed_scale_max: float | None = None,
                feed_scale_min: float | None = None,
                write_anyway: bool | None = None,
                draws: int = DEFAULT_CHECK_DRAWS, format: str | None = None,
                tool_table=None, tolerance: np.ndarray | None = None) -> RunResult:
    """``precontour run`` without writing (see the module docstring); :func:`write_run_outputs`
    writes.

    Parameters
    ----------
    program : str or Path
        The NC program or CL data.
    outputs : RunOutputs, optional
        Where the outputs go, checked before anything is computed (None: a library caller
        that keeps the result in memory).
    machine : str or Path
        A built-in machine's name or a machine file. No default, nor for ``controller``: a
        program compensated for another machine than the user's is wrong silently.
    controller : str
        The machine's controller the program runs with.
    tcp, dwell, corner_tolerance, corner_orientation_tolerance, max_samples
        Planning, as :func:`load_program_trajectory`.
    iterations : int
        Compensation passes, at most.
    gcode_tolerance : ndarray, shape (5,), optional
        The G-code decimation tolerance per axis
        (:func:`~.toolpath.writers.gcode_tolerances`).
    progress : callable, optional
        ``progress(done, total, message)`` between the stages.
    workers : int or None
        Processes for the two virtual-machine runs (1 by default; None: 2 when the computer
        has two cores or more and the trajectory :data:`PARALLEL_MIN_SAMPLES` samples; more
        than 1 needs the calling script's own code under ``if __name__ == "__main__":``, as
        for any use of :mod:`multiprocessing`).
    learn : int or LearningOptions
        Passes of learning against the realistic virtual machine after the compensation
        within the limits (0: none; skipped, with a notice, for a program not sampled at the
        servo period; segment by segment above :data:`~.compensation.pieces.AT_ONCE_SAMPLES`
        samples), every decision taken on the draws of the ensemble (the options', else
        ``ensemble``, default :class:`~.simulation.ensemble.MachineEnsemble` ()) and the
        result nowhere worse than uncompensated on them, block by block (each source line;
        :func:`~precontour.compensation.routes.learn_on_ensemble`).
    ensemble : MachineEnsemble, optional
        The draws learning, the feed search and the check on the draws run on (default
        :class:`~.simulation.ensemble.MachineEnsemble` ()).
    limits : LimitOptions
        Its ``min_speed`` is the floor of the local slow-downs that keep the limits, a
        fraction of the planned speed (below it the planned commands are kept); ``run``
        always keeps the limits.
    contour_tolerance : ToleranceOptions or ContourTolerance, optional
        Find the fastest motion whose compensated contour errors keep it on the realistic
        virtual machine (each search's result checked on the draws of ``ensemble``),
        between its ``feed_scale_min`` and ``feed_scale_max`` times the programmed feed, and
        the uncompensated baseline the same way
        (:func:`~.planning.tolerance.feed_within_tolerance`; ``RunResult.feed``); where the
        compensated one is not met even at the lowest feed, raise
        :class:`~precontour.errors.ToleranceError` naming the place unless
        ``write_anyway``.
    draws : int
        The machines both commands are checked on: the machine file's and ``draws - 1``
        draws of the ensemble (:func:`check_on_draws`; ``RunResult.draws``, None for 1).
    format : str, optional
        The program's format, instead of the one its extension says (as
        :func:`~precontour.toolpath.read_toolpath`'s).
    tool_table : optional
        G-code tool lengths (as :func:`load_program_trajectory`'s).
    min_speed, feed_scale_max, feed_scale_min, write_anyway, tolerance
        Former spellings of ``limits.min_speed``, of ``contour_tolerance``'s fields and of
        ``gcode_tolerance``, accepted with a DeprecationWarning (with an options object,
        give them there).

    Returns
    -------
    RunResult
        The plan, the compensation within the limits, the checks on the virtual machine and
        its draws, the G-code; ``summary()``, ``table()``, ``plot()``.

    Raises
    ------
    PrecontourError
        On bad input, and when the machine's limits cannot be kept.
    """
    if not is_whole_number(draws) or draws < 1:
        raise InputError(f"must be a whole number >= 1, got {draws!r}", field="--draws")
    gcode_tolerance = renamed_keyword(gcode_tolerance, tolerance, "gcode_tolerance",
                                      "tolerance")
    learning = learning_options(learn)
    limits = with_former_spellings(limits, LimitOptions, limit_options, "limits",
                                   min_speed=min_speed)
    if not limits.keep:
        raise InputError("run keeps the machine's limits (it writes a program a machine "
                         "runs)", field="--ignore-limits")
    contour_tolerance = with_former_spellings(
        contour_tolerance, ToleranceOptions, ToleranceOptions, "contour_tolerance",
        feed_scale_max=feed_scale_max, feed_scale_min=feed_scale_min,
        write_anyway=write_anyway)
    return _run_program(program, outputs, machine=machine, controller=controller, tcp=tcp,
                        dwell=dwell, corner_tolerance=corner_tolerance,
                        corner_orientation_tolerance=corner_orientation_tolerance,
                        max_samples=max_samples, iterations=iterations,
                        tolerance=gcode_tolerance,
                        progress=progress, workers=workers, learning=learning,
                        ensemble=ensemble, limits=limits, feed_options=contour_tolerance,
                        draws=draws, format=format, tool_table=tool_table)


def _run_program(program, outputs, *, machine, controller, tcp, dwell, corner_tolerance,
                 corner_orientation_tolerance,
                 max_samples, iterations, tolerance, progress, workers,
                 learning: LearningOptions, ensemble, limits: LimitOptions,
                 feed_options: ToleranceOptions, draws: int, format: str | None,
                 tool_table=None) -> RunResult:
    learn = learning.passes
    # the draws learning decides on and run checks on: the options', else ``ensemble``
    learning_ensemble = learning.ensemble or ensemble or MachineEnsemble()
    learner = controller if learning.controller is None else learning.controller
    min_speed = limits.min_speed
    timings: dict[str, float] = {}
    total = 4

    def step(done: int, message: str) -> None:
        check_signals()  # between stages: where a SIGTERM or Ctrl-C stops the run
        if progress is not None:
            progress(done, total, message)

    inputs = [program] + ([machine] if Path(str(machine)).exists() else [])
    if outputs is not None:
        # checked before computing, so that a bad output location is said at once
        check_run_outputs(outputs, inputs)
    tolerance = gcode_tolerances() if tolerance is None else np.asarray(tolerance, dtype=float)
    start = time.perf_counter()
    # every input is read and checked before the first progress line, so that a bad one
    # is the first thing said
    servo = load_servo(machine, controller)
    source = read_run_program(program, servo.machine, tcp=tcp, dwell=dwell,
                              max_samples=max_samples, format=format,
                              tool_table=tool_table)
    # the highest feed of the search: the programmed one for an NC program, twice CL data's
    feed_options = feed_options.for_format(source.format)
    contour_tolerance = feed_options.tolerance
    feed_scale_max, feed_scale_min = feed_options.feed_scale_max, feed_options.feed_scale_min
    write_anyway = feed_options.write_anyway
    step(0, f"plan {program}")
    planned, passthrough = plan_run_program(source, servo.machine, dwell=dwell,
                                            corner_tolerance=corner_tolerance,
                                            corner_orientation_tolerance=(
                                                corner_orientation_tolerance),
                                            max_samples=max_samples)
    # a final rest long enough for the corrections to taper to zero (the compensated program
    # ends at its programmed end point): the controller holds the last command anyway
    end_rest = required_final_rest(servo.models)
    as_planned = planned.n_samples
    planned = with_final_rest(planned, end_rest)
    final_rest_added = (planned.n_samples - as_planned) * planned.ts
    line = planned.line
    timings["plan"] = time.perf_counter() - start

    start = time.perf_counter()

    def round_progress(round_: int, message: str) -> None:
        step(1, f"{message}, round {round_}")

    feed = None
    if contour_tolerance is None:
        limited = compensate_within_limits(servo, planned, iterations=iterations,
                                           progress=round_progress, min_speed=min_speed)
        timings["compensate"] = time.perf_counter() - start
    else:
        programmed = planned
        if feed_scale_max != 1.0:
            step(1, f"plan {program} at {feed_scale_max:g} x the programmed feed")
            planned = with_final_rest(plan_run_program(
                source, servo.machine, dwell=dwell, corner_tolerance=corner_tolerance,
                corner_orientation_tolerance=corner_orientation_tolerance,
                max_samples=max_samples, feed_scale=feed_scale_max)[0], end_rest)
            line = planned.line
        def learned(limited):
            # a timing slowed beyond the learning's size is compensated without it
            if not can_learn(servo, limited.reference):
                return limited
            return learn_on_ensemble(servo, limited, learn, controller=learner,
                                     ensemble=learning_ensemble)

        refine = learned if learn and can_learn(servo, planned) else None
        feed = feed_within_tolerance(
            servo, planned, contour_tolerance, programmed=programmed,
            refine=refine, exempt_lines=_rapid_lines(source),
            feed_scale_max=feed_scale_max, min_speed=min(1.0, feed_scale_min / feed_scale_max),
            line=line, ensemble=MachineEnsemble() if ensemble is None else ensemble,
            progress=lambda message: step(1, message), limits_min_speed=min_speed,
            iterations=iterations, where="line" if source.format == "gcode" else "row")
        timings["feed within tolerance"] = time.perf_counter() - start
        found = feed.compensated
        if not found.met and not write_anyway:
            raise ToleranceError(_tolerance_message(feed, feed_scale_min))
        # the compensated search's commands, with the slow-downs against the upper-bound plan
        limited = replace(found.limited, slowdowns=found.slowdowns,
                          planned_index=found.planned_index)
    if learn and feed is None:
        if can_learn(servo, limited.reference):
            step(1, f"learn against the virtual machine ({learn} pass(es))")
            start = time.perf_counter()
            limited = learn_on_ensemble(
                servo, limited, learn, controller=learner,
                ensemble=learning_ensemble, planned=planned,
                # each command tried (a long program's segment by segment): learning on an
                # hour-long program runs for many minutes
                progress=lambda label, summary: step(
                    1, f"learn: {label}, worst draw tip max {summary['tip_max_um']:.3g} um"))
            timings["learn"] = time.perf_counter() - start

    simulated, checked = _check_run(limited, servo, machine, draws,
                                    learning_ensemble, workers=workers, step=step,
                                    timings=timings)

    step(3, "write G-code")
    start = time.perf_counter()
    commands = limited.result.trajectory
    learning = limited.result.learning
    info = ProgramInfo(machine=servo.machine.name, controller=controller,
                       method=f"contour pre-compensation within axis limits, passes "
                              f"{limited.result.iterations}"
                              + (f", learned against the virtual machine ({learn} pass(es)): "
                                 f"kept {learning.chosen}" if learning is not None else "")
                              + (f", fastest feed within {feed.tolerance.describe()} on the "
                                 "realistic virtual machine" if feed is not None else ""),
                       source=str(program))
    program_text = gcode_program(commands.t, commands.q, tolerance=tolerance, info=info,
                                 passthrough=passthrough, line=limited.line,
                                 axis_names=servo.machine.axis_names)
    timings["gcode"] = time.perf_counter() - start
    return RunResult(source=str(program), machine=servo.machine, controller=controller,
                     planned=planned, passthrough=passthrough, limited=limited,
                     simulated_before=simulated[0], simulated_after=simulated[1],
                     program=program_text, tolerance=tolerance, timings=timings,
                     stream=None if outputs is None else outputs.stream, feed=feed,
                     draws=checked, source_format=source.format,
                     final_rest_added=final_rest_added)


def _check_run(limited: LimitedCompensation, servo: Servo, machine: str | Path, draws: int,
               ensemble: MachineEnsemble, *, workers, step, timings: dict[str, float]):
    """``run``'s check of both commands on the realistic virtual machine (``machine``: the
    servo's machine as the caller named it, for the worker processes): the machine file's
    machine (:func:`check_on_virtual_machine`), then with ``draws`` > 1 that many draws of
    ``ensemble`` (:func:`check_on_draws`), a warning where the compensated commands are
    worse in whole. The two results (uncompensated, compensated) and the draws' check (None
    for one draw); ``step(done, message)`` reports, ``timings`` gets the seconds."""
    step(2, f"virtual machine, uncompensated and compensated "
            f"({limited.reference.n_samples} samples each)")
    start = time.perf_counter()
    simulated = check_on_virtual_machine(limited.reference, limited.result.trajectory.q,
                                         machine, servo.controller, workers=workers)
    timings["virtual machine (both)"] = time.perf_counter() - start
    if draws <= 1:
        return simulated, None
    ensemble = replace(ensemble, draws=draws)
    step(2, f"virtual machine, {draws - 1} more draw(s) of the machine, uncompensated "
            + ("(twice: its repeatability) " if ensemble.rerun_differs else "")
            + "and compensated")
    start = time.perf_counter()
    checked = check_on_draws(limited.reference, limited.result.trajectory.q, servo.machine,
                             servo.controller, simulated, line=limited.line, ensemble=ensemble)
    timings["virtual machine (draws)"] = time.perf_counter() - start
    worse = checked.worse_in_whole()
    if worse:
        warning(worse_in_whole_message(worse, learned=limited.result.learning is not None))
    return simulated, checked


def _rapid_lines(source: RunProgram) -> tuple[int, ...]:
    """The lines of a G-code program's rapids (G0): they cut nothing, so a contour-error
    tolerance does not apply to them (CL data has none)."""
    program = source.program
    if program is None:
        return ()
    rapid = np.asarray(program.rapid, dtype=bool)
    feed_lines = set(np.asarray(program.line)[~rapid].tolist())
    # a line that also holds a feed move (none in RS274, but safe) keeps its tolerance
    return tuple(sorted(set(np.asarray(program.line)[rapid].tolist()) - feed_lines))


def _tolerance_message(feed: FeedWithinTolerance, feed_scale_min: float) -> str:
    """One line: where the compensated search misses the tolerance, by how much."""
    misses = feed.compensated.misses
    first = misses[0]
    why = (f"even at {100 * feed_scale_min:g} % of the programmed feed"
           if first.floor or first.at_rest
           else f"after {feed.compensated.rounds} rounds of slowing down")
    more = f" (and {len(misses) - 1} more place(s))" if len(misses) > 1 else ""
    return (f"the compensated program does not keep the tolerance "
            f"{feed.tolerance.describe()} on the realistic virtual machine {why}: "
            f"{first.format()}{more}; --write-anyway writes it nevertheless")
