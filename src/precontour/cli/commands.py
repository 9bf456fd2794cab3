"""What each ``precontour`` command does: parse nothing, call one library function, print
(``run_<command>(args)``, bound to its parser in :mod:`.parser`). Each imports the stages it
needs when it runs, so that the command line starts without the numerical stack."""

from __future__ import annotations

import argparse
import math
import sys
import textwrap
import time
from contextlib import contextmanager
from pathlib import Path

from ..defaults import builtin_machines, default_max_samples
from ..errors import InputError
from ..files import OutputSet, input_files


@contextmanager
def _about(path):
    """Name ``path`` in an input error raised by a computation on its values."""
    try:
        yield
    except InputError as exc:
        located = exc.located(str(path))
        if located is exc:
            raise
        raise located from None


def run_predict(args: argparse.Namespace) -> int:
    from ..system import load_servo, predict
    from ..tables import (COMMAND_TOLERANCE, check_output_table, read_trajectory,
                         write_columns)

    start = time.perf_counter()
    inputs = input_files(args.trajectory, args.machine)
    check_output_table(args.output, inputs)
    servo = load_servo(args.machine, args.controller)
    machine = servo.machine
    # commands (e.g. pre-compensated ones) are measured against their own reference columns
    traj = read_trajectory(args.trajectory, kinematics=machine.kinematics,
                           tolerance=COMMAND_TOLERANCE)
    # long programs are predicted in pieces (bounded memory; compensation/pieces.py)
    with _about(args.trajectory):
        prediction = predict(servo, traj, tol_linear=args.tol_linear,
                             tol_rotary=args.tol_rotary)
    e = prediction.e
    columns = {"t": traj.t}
    columns.update({f"e{axis}": e[:, i] for i, axis in enumerate(machine.axis_names)})
    contour = prediction.contour
    if contour is not None:
        columns.update(eps_tip=contour.tip, eps_ori=contour.orientation)
    write_columns(args.output, columns, inputs=inputs)
    elapsed = time.perf_counter() - start
    print(f"predicted tracking errors of {traj.n_samples} samples "
          f"({traj.duration:.3f} s) on {machine.name}, controller {args.controller}")
    print(_axis_table(prediction.n_knots, prediction.max_abs_error, machine.axis_names))
    if contour is not None:
        print("predicted contour errors: " + _contour_line(contour))
    print(f"wrote {args.output} in {elapsed:.3f} s")
    return 0


def run_trajectory(args: argparse.Namespace) -> int:
    from ..machine.machine_file import load_machine
    from ..tables import check_output_table, trajectory_columns, write_columns
    from ..toolpath import PROGRAM_FORMATS, read_program, read_toolpath, toolpath_format
    from ..trajectory.builtin_paths import builtin_path
    from ..trajectory.generate import generate_trajectory, summarize, unfed_notice
    from ..trajectory.program import program_trajectory

    start = time.perf_counter()
    inputs = input_files(args.toolpath, args.machine)
    check_output_table(args.output, inputs)
    machine = load_machine(args.machine)
    ts = machine.servo_period if args.ts is None else args.ts
    if args.builtin:
        toolpath = builtin_path(args.builtin)
    elif toolpath_format(args.toolpath, args.format) in PROGRAM_FORMATS:
        program = read_program(args.toolpath, machine, tcp=args.tcp, format=args.format,
                               tool_table=args.tool_table)
        for notice in program.notices:
            print(f"precontour: {notice}", file=sys.stderr)
        traj = program_trajectory(program, machine, ts=ts, dwell=args.dwell,
                                  tolerance=args.corner_tol,
                                  orientation_tolerance=args.corner_ori_tol,
                                  max_samples=args.max_samples or default_max_samples())
        print(f"program {args.toolpath}: {program.n_moves} move(s) ({int(program.rapid.sum())} "
              f"rapid), {len(program.stops)} stop(s), {len(program.passthrough)} pass-through "
              f"line(s){', tool centre point mode' if program.tcp else ''}")
        toolpath = None
    else:
        if args.tcp:
            raise InputError("--tcp applies to G-code programs only (CL data gives the tool "
                             "tip already)", source=str(args.toolpath), field="--tcp")
        if args.tool_table is not None:
            raise InputError("--tool-table applies to G-code programs only (CL data gives the "
                             "tool tip already)", source=str(args.toolpath),
                             field="--tool-table")
        toolpath = read_toolpath(args.toolpath, machine=machine, feed_units=args.feed_units,
                                 format=args.format)
        said = unfed_notice(toolpath, args.feed)
        if said is not None:
            from ..errors import notice
            notice(said)
    if toolpath is not None:
        traj = generate_trajectory(toolpath, machine, feed=args.feed, ts=ts, dwell=args.dwell,
                                   max_samples=args.max_samples)
    write_columns(args.output, trajectory_columns(traj, machine.axis_names), inputs=inputs)
    print(summarize(traj, machine).format())
    print(f"wrote {args.output} in {time.perf_counter() - start:.3f} s")
    return 0


def run_compensate(args: argparse.Namespace) -> int:
    from ..options import LearningOptions, LimitOptions
    from ..system import compensate, load_servo
    from ..tables import check_output_table, read_trajectory, trajectory_columns, write_columns

    start = time.perf_counter()
    inputs = input_files(args.trajectory, args.machine)
    check_output_table(args.output, inputs)
    servo = load_servo(args.machine, args.controller)
    traj = read_trajectory(args.trajectory, kinematics=servo.kinematics)

    def progress(n, summary):
        print(f"  pass {n}: predicted tip max {summary['tip_max_um']:.3f} um, orientation max "
              f"{summary['ori_max_mrad']:.4f} mrad", file=sys.stderr)

    def learning_progress(label, summary):
        print(f"  {label} on the virtual machine: tip max {summary['tip_max_um']:.3f} um, "
              f"orientation max {summary['ori_max_mrad']:.4f} mrad", file=sys.stderr)

    with _about(args.trajectory):
        comp = compensate(servo, traj, method=args.method,
                          limits=LimitOptions(keep=not args.ignore_limits,
                                              min_speed=args.min_speed),
                          learn=LearningOptions(passes=args.learn,
                                                controller=args.learn_controller),
                          iterations=args.iterations, tol_linear=args.tol_linear,
                          tol_rotary=args.tol_rotary, progress=progress,
                          learning_progress=learning_progress)
    if comp.within_limits:
        print("within the machine's limits: "
              + (f"slowed in {len(comp.slowdowns)} window(s), +{comp.added_time:.3f} s, down "
                 f"to {100 * min(s.speed for s in comp.slowdowns):.1f} % of the speed"
                 if comp.slowdowns else "not slowed"))
        if comp.left_out:
            print(f"compensation left out in {len(comp.left_out)} window(s) where slowing "
                  f"down to {100 * args.min_speed:g} % of the speed or more could not keep "
                  "the limits: " + ", ".join(f"t = {a:.3f}-{b:.3f} s"
                                             for a, b in comp.left_out[:10]))
    write_columns(args.output, trajectory_columns(comp.commands, servo.axis_names),
                  inputs=inputs)
    print(f"{args.method} pre-compensation on {servo.machine.name}, controller "
          f"{args.controller}: {comp.passes} pass(es) kept")
    print("predicted before: " + _contour_line(comp.before))
    print("predicted after:  " + _contour_line(comp.after))
    if comp.learning is not None:
        learning, learner = comp.learning, comp.learning_controller
        print(f"learned against the virtual machine with friction ({args.learn} pass(es), "
              f"{learning.draws} draw(s), {learning.machine_runs} runs): kept {learning.chosen}")
        print(f"  virtual machine: controller {learner.name} ({learner.type}) "
              f"on the drives of {args.machine}")
        for name, summary in (("uncompensated", learning.uncompensated),
                              ("linear compensation", learning.linear),
                              ("kept", learning.kept)):
            print(f"  {name + ':':<21}" + _summary_line(summary))
    print(f"wrote {args.output} in {time.perf_counter() - start:.3f} s")
    return 0


def run_simulate(args: argparse.Namespace) -> int:
    from ..machine.machine_file import load_machine
    from ..prediction.contour import ReferencePath, contour_errors
    from ..simulation.virtual_machine import simulate
    from ..tables import (COMMAND_TOLERANCE, check_output_table, check_reference,
                         check_same_times, read_trajectory, write_columns)

    start = time.perf_counter()
    inputs = input_files(args.commands, args.reference, args.machine)
    check_output_table(args.output, inputs)
    machine = load_machine(args.machine)
    machine.controller(args.controller)
    commands = read_trajectory(args.commands, axis_names=machine.axis_names)
    if args.mode == "discrete" and not machine.at_servo_period(commands.ts):
        raise InputError(f"sample period {commands.ts:.9g} s differs from the machine's servo "
                         f"period {machine.servo_period:.9g} s (discrete mode samples at the "
                         "servo period)", source=str(args.commands), field="t")
    if commands.has_reference:
        check_reference(commands, machine.kinematics, source=str(args.commands),
                        tolerance=COMMAND_TOLERANCE)
    reference_traj = (read_trajectory(args.reference, kinematics=machine.kinematics)
                      if args.reference else commands)
    if args.reference:
        check_same_times(commands, reference_traj, source=str(args.reference))
    with _about(args.commands):
        result = simulate(commands.t, commands.q, machine, args.controller, mode=args.mode,
                          friction=args.friction == "on", ff_friction=args.ff_friction == "on",
                          inertia_scale=args.inertia_scale, damping_scale=args.damping_scale)
    columns = {"t": result.t}
    columns.update({axis: result.q_act[:, i] for i, axis in enumerate(machine.axis_names)})
    contour = None
    if reference_traj.has_reference:
        contour = contour_errors(ReferencePath.from_trajectory(reference_traj), result.q_act,
                                 machine.kinematics)
        columns.update(eps_tip=contour.tip, eps_ori=contour.orientation)
    write_columns(args.output, columns, inputs=inputs)
    print(f"simulated {commands.n_samples} samples on {machine.name}, controller "
          f"{args.controller}, {args.mode}, friction {args.friction}, feed-forward friction "
          f"{args.ff_friction}")
    print(_axis_table(None, result.max_abs_error, machine.axis_names))
    if contour is not None:
        print("measured contour errors: " + _contour_line(contour))
    print(f"wrote {args.output} in {time.perf_counter() - start:.3f} s")
    return 0


def run_demo(args: argparse.Namespace) -> int:
    from ..reports.demo_report import MACHINE_LABELS, format_table, run_demo as demo_run
    from ..reports.progress import ProgressLine

    paths = tuple(name.strip() for name in args.paths.split(",") if name.strip())
    progress = ProgressLine(sys.stderr)
    try:
        result = demo_run(args.report, paths=paths, iterations=args.iterations,
                          machine=args.machine, progress=progress)
    finally:
        progress.close()
    print(f"contour errors on {result.machine.name}: tool tip in um, orientation in mrad "
          f"(max, mean); reductions in % ({result.iterations} compensation pass(es) at most)")
    print(format_table(result.rows))
    print("machine: " + "; ".join(f"{key} = {text}" for key, text in MACHINE_LABELS.items()))
    print(f"wrote {len(result.files)} files to {result.out_dir} in "
          f"{result.timings['total']:.1f} s; open {result.files[-1]}")
    return 0


def run_compare(args: argparse.Namespace) -> int:
    from ..reports.compare_report import format_contour_table, run_compare as compare_run
    from ..reports.progress import ProgressLine

    progress = ProgressLine(sys.stderr)
    try:
        result = compare_run(args.report, builtin=args.builtin, trajectory=args.trajectory,
                             machine=args.machine, iterations=args.iterations,
                             model_errors=(() if args.model_error == 0 else
                                           (args.model_error / 100, -args.model_error / 100)),
                             progress=progress)
    finally:
        progress.close()
    print(f"{result.source} on {result.machine.name}, realistic virtual machine: measured "
          "contour errors (tool tip in um, orientation in mrad)")
    print(format_contour_table(result.contour_rows))
    print()
    print("The paper's claims, measured:")
    for claim in result.claims:
        print(claim.format())
    print(f"wrote {len(result.files)} files to {result.out_dir} in "
          f"{result.timings['total']:.1f} s; open {result.files[-1]}")
    return 0


def run_identify(args: argparse.Namespace) -> int:
    from ..identification import identify, parse_column_map, read_servo_log
    from ..machine.machine_file import load_machine, machine_data
    from ..tables import write_text

    start = time.perf_counter()
    inputs = input_files(args.log, args.machine)
    outputs = OutputSet(inputs)   # the machine file and the report: checked now, written as one
    outputs.file(args.output)
    base = load_machine(args.machine)
    if args.report is not None:
        from ..reports.identify_report import identify_report_files
        outputs.folder(args.report, identify_report_files(base.axis_names),
                       what="identification report")
    data, _ = machine_data(args.machine)
    columns = None if args.columns is None else args.columns.split(",")
    if args.column_map is not None:
        columns = parse_column_map(args.column_map)
    log = read_servo_log(args.log, fmt=args.format, columns=columns,
                         period=args.period, default_period=base.servo_period,
                         angle_scale=math.pi / 180 if args.angles == "deg" else 1.0,
                         axis_names=base.axis_names)
    result = identify(log, base, data, name=args.name, order=args.order,
                      base_controller=args.base_controller)
    with outputs:
        write_text(args.output, result.text, inputs=inputs)
        if args.report is not None:
            from ..reports.identify_report import write_identify_report
            index = write_identify_report(result, args.report)
    print(f"identified {len(result.axes)} axis/axes of {base.name} from {args.log} "
          f"({log.n_samples} samples, {log.period * 1e3:.6g} ms); base controller "
          f"{result.base_controller.name}")
    print(format_identification_table(result))
    for note in result.notes.values():
        print(note)
    if args.report is not None:
        print(f"report: {index}")
    print(f"wrote {args.output} (controller {args.name!r}, type tf) in "
          f"{time.perf_counter() - start:.1f} s")
    return 0


def format_identification_table(result) -> str:
    """The printed per-axis table of an identification."""
    lines = ["axis  order  fit % max|e|  held-out %   bandwidth Hz (base)  slowest pole rad/s (base)"]
    for row in result.summary_rows():
        # the slowest pole: the first of largest real part
        slow = max(row["poles"], key=lambda pole: pole.real)
        base_slow = max(row["base_poles"], key=lambda pole: pole.real)
        if row["identified"]:
            head = f"{row['axis']:>4}  {row['order']:5d}  {row['fit_pct']:12.2f}  {row['holdout_pct']:10.2f}"
        else:
            head = f"{row['axis']:>4}  {'base':>5}  {'-':>12}  {'-':>10}"
        lines.append(f"{head}   {row['bw']:7.2f} ({row['base_bw']:6.2f})   "
                     f"{slow:.4g} ({base_slow:.4g})")
    for axis, p in result.physical.items():
        name = result.letter(axis)   # keyed by q slot, printed by the machine's letter
        drive = result.base.drive(name)
        lines.append(f"{name}: J {p.J:.4g} kg m^2 (base {drive.J:.4g}), B {p.B:.4g} kg m^2/s "
                     f"(base {drive.B:.4g}), torque fit {p.torque_fit_pct:.2f} % over "
                     f"{p.windows} windows")
    return "\n".join(lines)


def run_excite(args: argparse.Namespace) -> int:
    from ..identification import excitation_trajectory, write_excitation
    from ..identification.excitation import check_excitation_output
    from ..machine.drives import AXES, ROTARY_AXES
    from ..machine.machine_file import load_machine

    start = time.perf_counter()
    check_excitation_output(args.output, input_files(args.machine))
    machine = load_machine(args.machine)
    letters = tuple(machine.axis_names)
    requested = "".join(letters) if args.axes is None else args.axes.strip()
    if not requested:
        raise InputError(f"no axis given; use letters of {''.join(letters)} (or leave --axes "
                         "out for all five)", field="--axes")
    given_letters = tuple(dict.fromkeys(requested.upper()))
    if "A" in given_letters and "A" not in letters and letters[3] == "B":
        from ..errors import notice

        notice("--axes: A read as the B axis of this B-C machine (the old spelling; write B)")
        given_letters = tuple(dict.fromkeys("B" if a == "A" else a for a in given_letters))
    unknown = [a for a in given_letters if a not in letters]
    if unknown:
        raise InputError(f"unknown axis {unknown[0]!r}; use letters of {''.join(letters)}",
                         field="--axes")
    # the library names the q slots X Y Z A C on every machine
    axes = tuple(AXES[letters.index(a)] for a in given_letters)
    given = {a: args.travel_rotary if a in ROTARY_AXES else args.travel_linear for a in axes}
    travel = {a: value for a, value in given.items() if value is not None}
    traj = excitation_trajectory(machine, travel=travel, safety=args.safety, axes=axes)
    write_excitation(args.output, traj, machine, inputs=input_files(args.machine))
    print(f"excitation for {machine.name}: {traj.n_samples} samples ({traj.duration:.1f} s), "
          f"axes {''.join(given_letters)} one at a time then together, within {args.safety:g} "
          "of the drive limits")
    print(f"wrote {args.output} in {time.perf_counter() - start:.2f} s")
    return 0


def run_export(args: argparse.Namespace) -> int:
    from ..workflow import export_commands

    start = time.perf_counter()
    result = export_commands(args.commands, args.output, format=args.format,
                             machine=args.machine, controller=args.controller,
                             gcode_tolerance=args.tol)
    blocks = f", {result.n_blocks} blocks" if result.n_blocks is not None else ""
    print(f"exported {result.n_samples} command samples as {result.format}{blocks}")
    print(f"wrote {result.path} in {time.perf_counter() - start:.3f} s")
    return 0


def run_run(args: argparse.Namespace) -> int:
    if args.timing is not None:
        return run_at_timing_command(args)
    if any(value is not None for value in (args.learn_from, args.repeat, args.timing_out,
                                            args.overlay)):
        raise InputError("--learn-from, --repeat, --overlay and --timing-out need --timing "
                         "(the controller's trace of the uncompensated program)",
                         field="--timing")
    from ..options import LimitOptions, ToleranceOptions
    from ..planning import ContourTolerance
    from ..reports.progress import ProgressLine
    from ..workflow import RunOutputs, run_program, write_run_outputs

    start = time.perf_counter()
    report_files = ()
    if args.report is not None:
        from ..reports.run_report import run_report_files
        report_files = run_report_files(tolerance=args.tolerance is not None)
    outputs = RunOutputs(program=args.output, stream=args.stream, commands=args.commands,
                         report=args.report, report_files=report_files)
    inputs = [args.program] + ([args.machine] if Path(args.machine).exists() else [])
    feed = ToleranceOptions(None if args.tolerance is None
                            else ContourTolerance.in_um(*args.tolerance),
                            feed_scale_max=args.feed_scale_max,
                            feed_scale_min=args.feed_scale_min, write_anyway=args.write_anyway)
    progress = ProgressLine(sys.stderr)
    try:
        result = run_program(args.program, outputs, machine=args.machine,
                             controller=args.controller, tcp=args.tcp, dwell=args.dwell,
                             corner_tolerance=args.corner_tol,
                             corner_orientation_tolerance=args.corner_ori_tol,
                             max_samples=args.max_samples,
                             iterations=args.iterations, gcode_tolerance=args.tol,
                             progress=progress, workers=1, learn=args.learn,
                             limits=LimitOptions(min_speed=args.min_speed),
                             contour_tolerance=feed, draws=args.draws, format=args.format,
                             tool_table=args.tool_table)
        files = []
        # -o, --stream, --commands and the report replace the old files together, or none
        with outputs.output_set(inputs):
            if args.report is not None:
                from ..reports.run_report import write_run_report
                progress(4, 4, f"report {args.report}")
                files += write_run_report(result, args.report)
            files = write_run_outputs(result, outputs, inputs) + files
    finally:
        progress.close()
    print(f"{args.program} on {result.machine.name}, controller {args.controller}: "
          "contour errors before and after compensation (before = the uncompensated "
          "commands, same timing)")
    print(result.table())
    print(f"wrote {', '.join(str(f) for f in files[:4])}"
          + (f" and {len(files) - 4} more" if len(files) > 4 else "")
          + f" in {time.perf_counter() - start:.1f} s")
    return 0


def run_batch_command(args: argparse.Namespace) -> int:
    from ..batch import run_batch
    from ..options import LimitOptions

    def progress(done: int, total: int, message: str) -> None:
        print(f"[{done}/{total}] {message}", flush=True)

    result = run_batch(args.programs, args.out_dir, machines=args.machine,
                       controller=args.controller, stream=args.stream, commands=args.commands,
                       executor=args.executor, jobs=args.jobs, progress=progress,
                       tcp=args.tcp, dwell=args.dwell, corner_tolerance=args.corner_tol,
                       corner_orientation_tolerance=args.corner_ori_tol,
                       max_samples=args.max_samples, iterations=args.iterations,
                       gcode_tolerance=args.tol, learn=args.learn,
                       limits=LimitOptions(min_speed=args.min_speed), draws=args.draws,
                       format=args.format, tool_table=args.tool_table)
    print(result.summary().splitlines()[-1])
    for entry in result.entries:
        for label, note in entry.notices:
            named = note if str(entry.job.program) in note else f"{entry.job.program}: {note}"
            print(f"precontour: {label}: {named}", file=sys.stderr)
    for entry in result.failed:
        print(f"precontour: error: {entry.error} (on {entry.job.machine})", file=sys.stderr)
    return 1 if result.failed else 0


def run_at_timing_command(args: argparse.Namespace) -> int:
    from ..cnc.run import run_at_timing
    from ..system import load_servo

    start = time.perf_counter()
    if args.stream is not None or args.report is not None or args.tolerance is not None:
        raise InputError("--stream, --report and --tolerance are not made with --timing (the "
                         "program's own blocks at the controller's timing)", field="--timing")
    servo = load_servo(args.machine, args.controller)
    columns = args.trace_columns.split(",") if args.trace_columns else None
    result = run_at_timing(servo, args.program, args.timing, args.output,
                           learn_from=args.learn_from, repeat=args.repeat,
                           commands_output=args.commands, tcp=args.tcp,
                           trace_output=args.timing_out, columns=columns,
                           angles=args.trace_angles, overlay_output=args.overlay)
    print(result.table())
    print(f"wrote {args.output} in {time.perf_counter() - start:.1f} s")
    return 0


def run_machines(args: argparse.Namespace) -> int:
    if args.template is not None:
        from ..machine.template import machine_template
        sys.stdout.write(machine_template(args.template))
        return 0
    print(format_machines_table(builtin_machines()))
    return 0


def format_machines_table(machines) -> str:
    """The table of ``precontour machines``: one row per machine and controller type."""
    rows = [("machine", "kinematics", "axes", "servo", "controllers (type)")]
    for m in machines:
        by_type: dict[str, list[str]] = {}
        for name, kind in m.controllers:
            by_type.setdefault(kind, []).append(name)
        groups = [f"{', '.join(names)} ({kind})" for kind, names in by_type.items()]
        for i, group in enumerate(groups):
            rows.append((m.name, m.kinematics, " ".join(m.axes), f"{m.servo_period * 1e3:g} ms",
                         group) if i == 0 else ("", "", "", "", group))
    widths = [max(len(row[k]) for row in rows) for k in range(4)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:4], widths)) + "  " + row[4]
             for row in rows]
    lines.append("")
    lines += [f"{m.name}: {m.description}" for m in machines]
    lines.append("")
    lines += textwrap.wrap(
        "Use one with --machine NAME --controller NAME; `precontour machines --template TYPE` "
        "prints an annotated machine file of that kinematics type "
        f"({', '.join(dict.fromkeys(m.kinematics for m in machines))}) to start your own "
        "from.", 99, break_on_hyphens=False)
    return "\n".join(lines)


def run_linuxcnc_config(args: argparse.Namespace) -> int:
    from ..machine.machine_file import load_machine
    from ..linuxcnc.config import check_config_folder, write_linuxcnc_config

    check_config_folder(args.output)
    machine = load_machine(args.machine)
    if args.drives == "simulated" and args.controller is None:
        raise InputError("--drives simulated needs --controller (a pid controller of the "
                         "machine file)", field="--controller")
    files = write_linuxcnc_config(machine, args.output, drives=args.drives,
                                  controller=args.controller)
    print(f"LinuxCNC configuration for {machine.name} ({len(files)} files) in {args.output}: "
          f"linuxcnc {args.output / 'machine.ini'} runs G-code; halrun -I -f "
          f"{args.output / 'stream.hal'} then halstreamer -c 0 FILE runs a --stream file")
    return 0


def run_linuxcnc_record(args: argparse.Namespace) -> int:
    from ..cnc.run import record_on_linuxcnc

    start = time.perf_counter()
    trace = record_on_linuxcnc(args.config, args.program, args.machine, args.output,
                               overlay=args.overlay)
    kind = "commands and actual positions" if trace.actual is not None else "commands"
    print(f"recorded {args.program} on {args.config}: {trace.n_samples} servo periods "
          f"({trace.n_samples * trace.period:.2f} s), {kind}; wrote {args.output} in "
          f"{time.perf_counter() - start:.1f} s")
    return 0


def _contour_line(errors) -> str:
    return _summary_line(errors.summary())


def _summary_line(s: dict) -> str:
    return (f"tip max {s['tip_max_um']:.3f} um, mean {s['tip_mean_um']:.3f} um; orientation "
            f"max {s['ori_max_mrad']:.4f} mrad, mean {s['ori_mean_mrad']:.4f} mrad")


def _axis_table(knots, max_abs_e, axis_names) -> str:
    """Per-axis table, by the machine's letters: knots (when given) and max |e| in um or
    mrad."""
    lines = ["axis  knots      max|e|" if knots is not None else "axis      max|e|"]
    for i, (axis, value) in enumerate(zip(axis_names, max_abs_e)):
        unit = "mrad" if i >= 3 else "um"
        count = f"  {knots[i]:5d}" if knots is not None else ""
        lines.append(f"{axis:>4}{count}  {value * 1e3:10.3f} {unit}")
    return "\n".join(lines)
