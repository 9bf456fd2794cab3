"""Command-line interface: ``precontour <command> ...``.

Each command reads files, calls the pipeline stages and writes files; no numerics live here.
User errors (bad files, values, names) print one line ``precontour: error: ...`` and exit 2.
Every command checks its output locations (:mod:`precontour.files`) before computing, and
passes its input files (trajectory, reference, machine file, program) as ``inputs`` so that no
output can overwrite one. Notices print as ``precontour: note: ...``.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import textwrap
import time
from contextlib import contextmanager
from pathlib import Path

# Only light modules at the top: the numerical stack (numpy, scipy, numba, matplotlib, and the
# compiled kernels) takes a second or more to load, so each command imports what it needs
# when it runs, and --help, --version and `machines` never load it. Defaults and names the
# help shows come from precontour.defaults (tests/test_cli.py checks what --help imports).
from . import __version__
from .defaults import (BUILTIN_MACHINES, BUILTIN_PATHS, COMPENSATION_METHODS, DEFAULT_CHECK_DRAWS,
                       COMPENSATION_TOL_LINEAR, COMPENSATION_TOL_ROTARY,
                       DEFAULT_CORNER_ORIENTATION_TOLERANCE, DEFAULT_CORNER_TOLERANCE,
                       DEFAULT_DWELL, DEFAULT_FEED,
                       DEFAULT_FEED_SCALE_MAX, DEFAULT_FEED_SCALE_MAX_CL, DEFAULT_FEED_SCALE_MIN, DEFAULT_LEARNING_PASSES, DEFAULT_MIN_SPEED, DEFAULT_SAFETY, DEFAULT_TRAVEL_LINEAR,
                       DEFAULT_TRAVEL_ROTARY, EXPORT_FORMATS, FIT_TOL_LINEAR, FIT_TOL_ROTARY,
                       GCODE_TOL_LINEAR, GCODE_TOL_ROTARY, LOG_FORMATS, TOOLPATH_FORMATS,
                       builtin_machines, default_max_samples)
from .errors import NOTICES, InputError, PrecontourError
from .files import OutputSet, Terminated, input_files, interruption, sigterm_as_exception
from .parallel import using_jobs

EXIT_USAGE = 2


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_USAGE
    notices = logging.StreamHandler(sys.stderr)
    notices.setFormatter(_NoticeFormat())
    NOTICES.addHandler(notices)
    propagate, NOTICES.propagate = NOTICES.propagate, False
    try:
        with sigterm_as_exception(), using_jobs(getattr(args, "jobs", None)):
            return args.run(args)
    except PrecontourError as exc:
        print(f"precontour: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError:
        print("precontour: error: out of memory (the input is too large for this machine)",
              file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # e.g. an input that vanished or turned unreadable while read
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"precontour: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except (Terminated, KeyboardInterrupt, SystemError) as exc:
        # SystemError: a compiled call that a second signal interrupted
        stop = interruption(exc)
        if stop is None:
            raise
        return _stopped(stop)
    finally:
        NOTICES.removeHandler(notices)
        NOTICES.propagate = propagate


class _NoticeFormat(logging.Formatter):
    """``precontour: note: ...``, or ``precontour: warning: ...`` for a warning
    (:func:`precontour.errors.warning`)."""

    def format(self, record: logging.LogRecord) -> str:
        return f"precontour: {getattr(record, 'label', 'note')}: {record.getMessage()}"


def _stopped(exc: BaseException) -> int:
    """The one line and the exit code of a command stopped by SIGTERM or Ctrl-C."""
    if isinstance(exc, Terminated):
        print("precontour: terminated", file=sys.stderr)
        return int(exc.code)
    print("precontour: interrupted", file=sys.stderr)
    return 130


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split("\n"))


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


class _HelpFormatter(argparse.HelpFormatter):
    """argparse's help layout, without breaking lines at hyphens: names such as pid-low,
    --corner-tol or linuxcnc-xyzac-trt stay whole."""

    def _split_lines(self, text, width):
        return textwrap.wrap(self._whitespace_matcher.sub(" ", text).strip(), width,
                             break_on_hyphens=False)

    def _fill_text(self, text, width, indent):
        return textwrap.fill(self._whitespace_matcher.sub(" ", text).strip(), width,
                             initial_indent=indent, subsequent_indent=indent,
                             break_on_hyphens=False)


class _Parser(argparse.ArgumentParser):
    """argparse's parser, whose error for a missing ``--machine`` or ``--controller`` also
    says where the built-in ones are listed."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        if "required" in message and ("--machine" in message or "--controller" in message):
            message += ("; `precontour machines` lists the built-in machines ("
                        + ", ".join(BUILTIN_MACHINES) + ") and their controllers")
        super().error(message)


#: ``controller=REQUIRED`` in :func:`_add_machine_options`: ``--controller`` has no default.
REQUIRED = object()
#: The machine and controller of the commands that keep a default (not ``run``, ``export``).
DEFAULT_MACHINE = "zhang2013"
DEFAULT_CONTROLLER = "pid-low"


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="precontour",
        description="Predict and pre-compensate five-axis CNC contour errors "
                    "(Zhang, Yuen & Altintas 2013).")
    parser.add_argument("--version", action="version", version=f"precontour {__version__}")
    commands = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")
    for add_command in (_add_predict_command, _add_trajectory_command, _add_compensate_command,
                        _add_simulate_command, _add_demo_command, _add_compare_command,
                        _add_identify_command, _add_excite_command, _add_export_command,
                        _add_run_command, _add_batch_command, _add_machines_command,
                        _add_linuxcnc_config_command):
        add_command(commands)
    for name in JOBS_COMMANDS:
        _add_jobs_option(commands.choices[name])
    return parser


#: The commands with independent work to spread over the cores (``--jobs``).
JOBS_COMMANDS = ("predict", "trajectory", "compensate", "simulate", "demo", "compare", "run",
                 "batch")


def _add_jobs_option(parser: argparse.ArgumentParser) -> None:
    """``--jobs N``: how much runs at once (:func:`precontour.parallel.using_jobs`)."""
    parser.add_argument("--jobs", type=_positive_int, default=None, metavar="N",
                        help="pieces of independent work run at once: threads for the chunks "
                             "of the compiled loops, the axes and the draws of the virtual "
                             "machine; for batch, programs (default: all cores, or "
                             "NUMBA_NUM_THREADS where set); results do not depend on it")


def _add_predict_command(commands) -> None:
    predict = commands.add_parser(
        "predict", help="predict each axis's tracking error in closed form",
        description="Fit each axis command with a minimum-jerk C3 quintic spline and predict "
                    "its tracking error (command minus actual) in closed form.")
    predict.add_argument("trajectory", type=Path,
                         help="trajectory file (.csv/.npz/.parquet) with columns t,X,Y,Z,A,C "
                              "(s, mm, rad), uniformly sampled")
    _add_machine_options(predict)
    _add_fit_options(predict)
    _add_output(predict, help="output file (.csv/.npz/.parquet): t,eX,eY,eZ,eA,eC")
    predict.set_defaults(run=run_predict)


def _add_trajectory_command(commands) -> None:
    trajectory = commands.add_parser(
        "trajectory", help="tool path in, smooth time-stamped five-axis trajectory out",
        description="Read a tool path (CL-data CSV or APT CL data) or take a built-in path, "
                    "fit C3 geometric splines, plan a jerk-limited feed within the machine's "
                    "limits and sample axis commands at the servo period. A G-code program "
                    "is executed as a CNC does: its block times (G93/G94 feeds), rapids at "
                    "the machine's rapid rate, stops, and jerk-limited blending of the "
                    "blocks within the axis limits; the output then has a 'line' column.")
    source = trajectory.add_mutually_exclusive_group(required=True)
    source.add_argument("toolpath", nargs="?", type=Path,
                        help="tool path file: .csv (Px,Py,Pz,Oi,Oj,Ok[,F]), .apt/.cls/.cl, "
                             "or G-code .nc/.ngc/.gcode/.tap/.mpf")
    source.add_argument("--builtin", choices=BUILTIN_PATHS, metavar="NAME",
                        help=f"built-in test path: {', '.join(BUILTIN_PATHS)}")
    _add_toolpath_format_option(trajectory)
    _add_machine_options(trajectory, controller=None)
    trajectory.add_argument("--feed", type=_positive_float, default=DEFAULT_FEED, metavar="MM_S",
                            help=f"maximum tool tip feed in mm/s for CL data and built-in paths "
                                 f"(default {DEFAULT_FEED:g}); a G-code program keeps its own")
    trajectory.add_argument("--ts", type=_positive_float, default=None, metavar="S",
                            help="sampling period in s (default: the machine's servo period)")
    trajectory.add_argument("--feed-units", choices=("mm/min", "mm/s"), default="mm/min",
                            help="unit of programmed feeds in CL-data CSV/APT (default mm/min)")
    _add_planning_options(trajectory)
    _add_output(trajectory, help="output file (.csv/.npz/.parquet): "
                                 "t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok")
    trajectory.set_defaults(run=run_trajectory)


def _add_compensate_command(commands) -> None:
    compensate = commands.add_parser(
        "compensate", help="pre-compensate axis commands so predicted contour errors cancel",
        description="Predict the contour errors of a trajectory and rewrite its axis commands "
                    "(orientation first, then tool tip) so that they cancel.")
    compensate.add_argument("trajectory", type=Path, help=TRAJECTORY_HELP)
    _add_machine_options(compensate)
    compensate.add_argument("--method", choices=COMPENSATION_METHODS, default="contour",
                            help="contour: contour-error pre-compensation (default); tracking: "
                                 "add the predicted axis tracking errors (the paper's baseline)")
    _add_iterations_option(compensate, help="largest number of compensation passes; stops early "
                                            "when the predicted contour errors stop improving "
                                            "(default 1)")
    _add_learn_option(compensate, DEFAULT_LEARNING_PASSES,
                      help="passes of learning against the virtual machine with friction "
                           "(discrete control at the servo period, Stribeck friction, "
                           "friction feed-forward) where the linear model misses: stops, "
                           "reversals, the final dwell; keeps a command only if it is "
                           "nowhere worse there than the uncompensated one, on each of "
                           "5 draws of that machine (friction, J, B, encoder) and in "
                           "every 0.1 s window; each pass costs up to 27 runs of the 5 draws; "
                           f"0 = off (default {DEFAULT_LEARNING_PASSES}; contour method "
                           "only)")
    compensate.add_argument("--ignore-limits", action="store_true",
                            help="compensate and learn without keeping the machine's velocity, "
                                 "acceleration and jerk limits (no local slow-down, unsmoothed "
                                 "learning updates): the commands may break the "
                                 "limits, so 'export' refuses them as G-code or halstreamer")
    compensate.add_argument("--learn-controller", metavar="NAME", default=None,
                            help="controller the virtual machine runs when learning (default: "
                                 "--controller; for a controller of type tf, which has no "
                                 "drives or friction, the controller its 'base' key names, "
                                 "e.g. the base controller of 'precontour identify', run on "
                                 "the machine file's drives: identified J, B and friction when "
                                 "the log had motor currents)")
    _add_min_speed_option(compensate)
    _add_fit_options(compensate, linear=COMPENSATION_TOL_LINEAR, rotary=COMPENSATION_TOL_ROTARY)
    _add_output(compensate, help="output file: t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok")
    compensate.set_defaults(run=run_compensate)


def _add_simulate_command(commands) -> None:
    simulate = commands.add_parser(
        "simulate", help="run axis commands on the time-domain virtual machine",
        description="Simulate the five drives (discrete controllers at the servo period, "
                    "friction, feed-forward friction compensation) following axis commands.")
    simulate.add_argument("commands", type=Path, help="command file with t,X,Y,Z,A,C")
    _add_machine_options(simulate)
    simulate.add_argument("--reference", type=Path,
                          help="reference trajectory (with Px..Ok) to measure contour errors "
                               "against (default: the command file's own Px..Ok, if any)")
    simulate.add_argument("--mode", choices=("discrete", "continuous"), default="discrete",
                          help="discrete controller with zero-order hold (default) or the "
                               "continuous-equivalent controller (the exact linear model)")
    simulate.add_argument("--friction", choices=("on", "off"), default="on",
                          help="friction in the drives (default on)")
    simulate.add_argument("--ff-friction", choices=("on", "off"), default="on",
                          help="feed-forward friction compensation (default on)")
    simulate.add_argument("--inertia-scale", type=_positive_float, default=1.0, metavar="K",
                          help="true inertia = K x nominal (mis-identified machine; default 1)")
    simulate.add_argument("--damping-scale", type=_nonnegative_float, default=1.0, metavar="K",
                          help="true damping = K x nominal (default 1)")
    _add_output(simulate, help="output file: t,X,Y,Z,A,C (actual) [+ eps_tip,eps_ori]")
    simulate.set_defaults(run=run_simulate)


def _add_demo_command(commands) -> None:
    demo = commands.add_parser(
        "demo", help="re-run the paper's evaluation on the virtual machine, write a report",
        description="For each built-in path and both PID controllers: predict, contour "
                    "pre-compensate, and run the uncompensated and pre-compensated commands on "
                    "the realistic virtual machine (discrete PID, friction, feed-forward "
                    "friction compensation) and on the exact linear model; print the paper's "
                    "Tables 3-4 with ours next to them and write figures, tables and an "
                    "index.html. Only the report's own files are overwritten.")
    _add_machine_options(demo, controller=None)
    _add_report_option(demo, Path("precontour-demo"))
    demo.add_argument("--paths", default="paper", metavar="NAMES",
                      help="comma-separated built-in paths out of "
                           f"{','.join(BUILTIN_PATHS)} (default: paper)")
    _add_iterations_option(demo)
    demo.set_defaults(run=run_demo)


def _add_compare_command(commands) -> None:
    compare = commands.add_parser(
        "compare", help="compare controllers and compensation methods, answer the paper's "
                        "claims with measurements",
        description="On the realistic virtual machine (discrete control at the servo period, "
                    "friction, feed-forward friction compensation) run the sliding-mode "
                    "controller, and P-PI and PID controllers uncompensated, with axis "
                    "tracking-error and with contour-error pre-compensation; write the "
                    "paper's Figs. 11-16, tables and an index.html, and print the measured "
                    "answer to each of the paper's claims. Only the report's own files are "
                    "overwritten.")
    source = compare.add_mutually_exclusive_group()
    source.add_argument("trajectory", nargs="?", type=Path,
                        help=f"{TRAJECTORY_HELP}, sampled at the servo period")
    # no argparse choices: an unknown name then gets the one-line error of the others
    source.add_argument("--builtin", metavar="NAME",
                        help=f"built-in path: {', '.join(BUILTIN_PATHS)} (default: paper)")
    _add_machine_options(compare, controller=None)
    _add_report_option(compare, Path("precontour-compare"))
    _add_iterations_option(compare, help="largest number of contour compensation passes "
                                         "(default 1; the tracking baseline is always the "
                                         "paper's single pass)")
    compare.add_argument("--model-error", type=_nonnegative_float, default=20.0, metavar="PCT",
                         help="also run sliding mode and P-PI on plants whose J and B are PCT "
                              "%% above and below the model both controllers use, as on a real "
                              "machine (the paper's Fig. 11 ranking under model error; default "
                              "20, 0 leaves it out)")
    compare.set_defaults(run=run_compare)


def _add_identify_command(commands) -> None:
    ident = commands.add_parser(
        "identify", help="identify the drives' closed loops from a servo log, write a machine file",
        description="Read a servo log (commanded and actual axis positions at the servo rate, "
                    "optionally motor currents I_X..I_C; the machine's axis letters, B for A "
                    "on a B-C machine), identify each moving axis's closed "
                    "loop x/X (output-error least squares, stable, order chosen on a held-out "
                    "part) and, with currents, the drives' J, B and friction; write the base "
                    "machine plus a controller of type tf.")
    ident.add_argument("log", type=Path,
                       help="servo log: .csv/.npz/.parquet with t,X..C,X_act..C_act[,I_X..I_C], "
                            "LinuxCNC halsampler output, a halscope log, a Heidenhain TNCscope "
                            ".sco file, a Sinumerik Operate trace (.xml), a TwinCAT Scope View "
                            "CSV export, or any CSV whose columns --columns or --column-map "
                            "names")
    _add_machine_options(ident, controller=None,
                         machine_help="base machine: built-in name or machine TOML file")
    _add_output(ident, help="identified machine file (.toml)")
    ident.add_argument("--name", default="identified",
                       help="name of the identified controller (default: identified)")
    ident.add_argument("--order", default="auto", metavar="auto|N",
                       help="model order per axis: auto (default) or a number")
    _add_report_option(ident, help="also write figures (Bode, residuals) and index.html to DIR")
    ident.add_argument("--format", choices=LOG_FORMATS, default=None,
                       help="log format (default: by suffix and first line: .sco TNCscope, "
                            ".xml Sinumerik, a first line 'Name' TwinCAT, .csv/.npz/.parquet "
                            "table (a .csv with --columns or --column-map: csv); other text: "
                            "halscope if the first line says 'Sampling period is', else "
                            "halsampler)")
    names = ident.add_mutually_exclusive_group()
    names.add_argument("--columns", metavar="NAMES",
                       help="comma-separated names of the log's columns in order (halsampler, "
                            "csv, or the channels of halscope and the traces): t, n (sample "
                            "number), X..C, X_act..C_act, I_X..I_C, line (program line); empty "
                            "to skip")
    names.add_argument("--column-map", metavar="MAP",
                       help="the columns by the names in the file, as HEADER=NAME pairs "
                            "separated by commas, e.g. 's soll/X=X,s ist/X=X_act' (csv, "
                            "halscope and the traces; other channels are not read; default for "
                            "the traces: recognised by their names)")
    ident.add_argument("--period", type=_positive_float, metavar="S",
                       help="sample period in s for logs without a t column (default: the "
                            "machine's servo period; halscope logs give theirs)")
    ident.add_argument("--angles", choices=("rad", "deg"), default="rad",
                       help="unit of the rotary axes in the log (default rad; LinuxCNC and "
                            "the controllers' traces use deg)")
    ident.add_argument("--base-controller", metavar="NAME",
                       help="base controller kept for axes the log cannot identify (default: "
                            "the machine's first linear controller)")
    ident.set_defaults(run=run_identify)


def _add_excite_command(commands) -> None:
    excite = commands.add_parser(
        "excite", help="write a safe identification motion to record a servo log with",
        description="Per axis: jerk-limited steps, reversals at three speeds and a multi-sine "
                    "riding on a drift speed; one axis at a time, then all together; within "
                    "a fraction of the machine's velocity, acceleration and jerk limits.")
    _add_machine_options(excite, controller=None)
    _add_output(excite, help="output: .csv/.npz/.parquet (t,X,Y,Z,A,C; t,X,Y,Z,B,C on a B-C "
                             "machine), or .ngc / .txt "
                             "(G-code / halstreamer, needs precontour.toolpath.writers)")
    excite.add_argument("--safety", type=_positive_float, default=DEFAULT_SAFETY, metavar="F",
                        help=f"fraction of v_max, a_max, j_max used (default {DEFAULT_SAFETY:g})")
    excite.add_argument("--travel-linear", type=_positive_float, default=None,
                        metavar="MM", help="half travel of X, Y, Z around the start (default "
                                           f"{DEFAULT_TRAVEL_LINEAR:g} mm, shortened to fit an "
                                           "axis's travel; one given must fit)")
    excite.add_argument("--travel-rotary", type=_positive_float, default=None,
                        metavar="RAD", help="half travel of the rotary axes (A, C; B, C on a "
                                            "B-C machine) around the start (default "
                                            f"{DEFAULT_TRAVEL_ROTARY:g} rad, shortened to fit "
                                            "an axis's travel; one given must fit)")
    excite.add_argument("--axes", default=None, metavar="AXES",
                        help="axes to excite, by the machine's letters (default all five: "
                             "XYZAC, or XYZBC on a B-C machine)")
    excite.set_defaults(run=run_excite)


def _add_export_command(commands) -> None:
    export = commands.add_parser(
        "export", help="write axis commands as a program a CNC runs (G-code, halstreamer)",
        description="Write a command file as machine-axis G-code (G90 G93 inverse-time G1 "
                    "blocks, decimated within --tol), as a LinuxCNC halstreamer file (one "
                    "line X Y Z A C per servo period) or as a table. Programs must keep the "
                    "machine's axis limits; commands that do not are refused.",
        epilog=_machines_epilog())
    export.add_argument("commands", type=Path,
                        help="command file (.csv/.npz/.parquet) with t,X,Y,Z,A,C (s, mm, rad), "
                             "uniformly sampled")
    export.add_argument("--format", choices=EXPORT_FORMATS, default=None,
                        help="gcode, halstreamer, csv, npz or parquet (default: from the "
                             "extension of -o; needed for halstreamer)")
    _add_machine_options(export, required=True, controller="",
                         machine_help="built-in machine name or machine TOML file, for the "
                                      "limits and the header")
    _add_tol_option(export)
    _add_output(export, help="output file")
    export.set_defaults(run=run_export)


def _add_run_command(commands) -> None:
    run = commands.add_parser(
        "run", help="program in, compensated program out",
        description="Read an NC program (G-code of machine axis positions or, in tool "
                    "centre point mode, of tool tip positions: see --tcp) or CL data, "
                    "plan the trajectory, predict and contour pre-compensate the axis "
                    "commands, keep them within the machine's axis limits (slowing down "
                    "locally and compensating again where needed), check uncompensated and "
                    "compensated commands on the realistic virtual machine, and write the "
                    "compensated program. Progress goes to stderr; a table of the results, "
                    "with the line and time of the largest errors, to stdout.",
        epilog=_machines_epilog())
    run.add_argument("program", type=Path,
                     help="NC program (.nc/.ngc/.gcode/...) or CL data (.csv/.apt)")
    _add_toolpath_format_option(run)
    _add_machine_options(run, required=True, controller=REQUIRED)
    _add_planning_options(run)
    _add_iterations_option(run)
    _add_learn_option(run, 0,
                      help="passes of learning against the virtual machine with friction "
                           "(as for compensate), after the compensation within limits: each "
                           "learning update smoothed, a command kept only if it keeps the "
                           "limits and is nowhere worse there than the uncompensated one; "
                           "each pass costs up to 27 virtual-machine runs; with --tolerance, in "
                           "every round of the search (default 0 = off)")
    _add_min_speed_option(run)
    _add_tol_option(run)
    run.add_argument("--tolerance", type=_contour_tolerance, default=None,
                     metavar="TIP_UM[,ORI_MRAD]",
                     help="contour-error tolerance, tool tip in um and optionally orientation "
                          "in mrad: find the fastest motion whose compensated contour errors "
                          "keep it everywhere on the realistic virtual machine (worst of 5 "
                          "draws of friction, J, B and encoder), slowing down locally and "
                          "smoothly, and the fastest uncompensated motion with the same "
                          "retiming (the baseline); print the cycle times as programmed, "
                          "of the baseline and compensated, and the errors of each. Where "
                          "even the lowest feed misses it, or slowing down does not lower the "
                          "error (friction where an axis stops or creeps: not slowed further), "
                          "say where and exit with an error (see --write-anyway)")
    run.add_argument("--feed-scale-max", type=_positive_float, default=None, metavar="K",
                     help="with --tolerance: the highest feed, K times the programmed feed "
                          "(above 1 where the program's feed was itself conservative; the "
                          "axis limits hold whatever K; default "
                          f"{DEFAULT_FEED_SCALE_MAX:g} for an NC program, its programmed feed "
                          f"the upper bound, and {DEFAULT_FEED_SCALE_MAX_CL:g} for CL data, "
                          "whose feed is a CAM system's request)")
    run.add_argument("--feed-scale-min", type=_speed_fraction, default=DEFAULT_FEED_SCALE_MIN,
                     metavar="FRACTION",
                     help="with --tolerance: the lowest feed, as a fraction of the "
                          "programmed feed, to which the motion may be slowed to keep the "
                          f"tolerance (default {DEFAULT_FEED_SCALE_MIN:g})")
    run.add_argument("--write-anyway", action="store_true",
                     help="with --tolerance: write the compensated program even where it "
                          "does not keep the tolerance (the table says where)")
    run.add_argument("--draws", type=_positive_int, default=DEFAULT_CHECK_DRAWS, metavar="N",
                     help="check both commands on N machines: the machine file's and N - 1 "
                          "draws of its friction, inertia, damping and a noisy encoder (those "
                          "learning decides on), and give the median and the worst draw, "
                          "where friction at a stop makes one exact machine's answer a coin "
                          f"toss; each draw costs two virtual-machine runs; 1 = the machine "
                          f"file's only (default {DEFAULT_CHECK_DRAWS})")
    _add_output(run, help="compensated G-code program (.ngc, .nc, ...)")
    run.add_argument("--stream", type=Path, default=None, metavar="OUT.txt",
                     help="also write a halstreamer file (one line per servo period)")
    run.add_argument("--commands", type=Path, default=None, metavar="OUT.csv",
                     help="also write the compensated commands with the reference and the "
                          "source line of each sample: t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok,line")
    _add_report_option(run, help="also write figures, the table and an index.html to DIR")
    timing = run.add_argument_group(
        "at the controller's own timing (docs/controller.md)",
        "With --timing, run compensates for the timing the controller itself produced for the "
        "program as written and gives the program back, every line as written, with only the "
        "end points of its straight feed moves corrected (G-code programs).")
    timing.add_argument("--timing", default=None, metavar="TRACE",
                        help="the controller's servo trace of the uncompensated program "
                             "(commanded positions per servo period and the program line: a "
                             "servo log in any format identify reads, angles in degrees), or "
                             "linuxcnc:DIR to record it by running the program on the LinuxCNC "
                             "configuration DIR (precontour linuxcnc-config) headless")
    timing.add_argument("--learn-from", default=None, metavar="TRACE",
                        help="with --timing: learn the corrections from this trace of an "
                             "earlier run of the program on the machine (commanded and actual "
                             "positions; uncompensated or compensated), instead of predicting "
                             "them: the measured contour error at each point of the program, "
                             "through the identified model's inverse")
    timing.add_argument("--repeat", default=None, metavar="TRACE",
                        help="with --learn-from: a second trace of the uncompensated program "
                             "(with actual positions): a line counts as worse only beyond the "
                             "two uncompensated runs' difference on it")
    timing.add_argument("--overlay", type=Path, default=None, metavar="OUT.txt",
                        help="with --timing, on LinuxCNC: write the correction as a servo-rate "
                             "overlay instead of into the blocks: this halstreamer file (the "
                             "compensated minus the recorded commands per joint, mm and "
                             "degrees, from the first move), and as -o the program as written "
                             "with M62 P0 on its first move's line, which starts it (a "
                             "configuration of linuxcnc-config --drives simulated adds it "
                             "between motion and the position loops)")
    timing.add_argument("--timing-out", type=Path, default=None, metavar="TRACE.csv",
                        help="with --timing linuxcnc:DIR: also write the recorded trace (t, "
                             "X..C, X_act..C_act with simulated drives, line; mm, rad)")
    timing.add_argument("--trace-columns", default=None, metavar="NAMES",
                        help="comma-separated names of a text trace's columns in order "
                             "(as identify --columns: t, n, X..C, X_act..C_act, line; empty "
                             "to skip)")
    timing.add_argument("--trace-angles", choices=("deg", "rad"), default=None,
                        help="unit of the rotary axes in the traces (default: rad for "
                             ".csv/.npz/.parquet tables, deg for controllers' text traces)")
    run.set_defaults(run=run_run)


def _add_batch_command(commands) -> None:
    batch = commands.add_parser(
        "batch", help="run over many programs and machines, one output set per program",
        description="Run every program given (files, or folders of them) on every machine "
                    "given, as precontour run does, each into its own output set in "
                    "--out-dir (the program's own name; under a folder per machine where "
                    "there are several). The programs run side by side, on the cores of "
                    "this computer (--jobs) or on the workers of a Dask cluster "
                    "(--executor); a program that fails is reported with its error and the "
                    "others go on. A line per program goes to stdout as it ends; exits 1 "
                    "where any failed.",
        epilog=_machines_epilog())
    batch.add_argument("programs", nargs="+", type=Path, metavar="PROGRAM",
                       help="NC programs or CL data, or folders of them")
    batch.add_argument("--machine", action="append", required=True,
                       help="built-in machine name or machine TOML file; repeat for a fleet "
                            "(required; `precontour machines` lists the built-in ones)")
    batch.add_argument("--controller", required=True,
                       help="controller name in the machine files (required)")
    batch.add_argument("--out-dir", type=Path, required=True, metavar="DIR",
                       help="folder of the outputs, created if missing (never an input's "
                            "own file)")
    batch.add_argument("--stream", action="store_true",
                       help="also write each program's halstreamer file (NAME.txt)")
    batch.add_argument("--commands", action="store_true",
                       help="also write each program's command table (NAME.csv)")
    batch.add_argument("--executor", default=None, metavar="dask://HOST:PORT",
                       help="run the programs on the workers of this Dask distributed "
                            "scheduler (pip install 'precontour[dask]') instead of --jobs "
                            "processes here")
    _add_toolpath_format_option(batch)
    _add_planning_options(batch)
    _add_iterations_option(batch)
    _add_learn_option(batch, 0, help="passes of learning, as for run (default 0 = off)")
    _add_min_speed_option(batch)
    _add_tol_option(batch)
    batch.add_argument("--draws", type=_positive_int, default=DEFAULT_CHECK_DRAWS, metavar="N",
                       help="check both commands on N machines, as for run (default "
                            f"{DEFAULT_CHECK_DRAWS})")
    batch.set_defaults(run=run_batch_command)


def _add_machines_command(commands) -> None:
    machines = commands.add_parser(
        "machines", help="list the built-in machines, or print an annotated machine file",
        description="List the built-in machines (--machine NAME) with their kinematics type, "
                    "axes and controllers (--controller NAME). With --template TYPE, print "
                    "instead a machine file of that kinematics type with every key, its unit "
                    "and what it means (the values of a built-in machine of that type), to "
                    "save and edit: precontour machines --template TYPE > mymachine.toml")
    kinematics = tuple(dict.fromkeys(m.kinematics for m in builtin_machines()))
    machines.add_argument("--template", choices=kinematics, metavar="TYPE",
                          help=f"kinematics type: {', '.join(kinematics)}")
    machines.set_defaults(run=run_machines)


def _add_linuxcnc_config_command(commands) -> None:
    lcnc = commands.add_parser(
        "linuxcnc-config", help="write a LinuxCNC configuration for running run's outputs",
        description="Write a LinuxCNC configuration folder for the machine: INI with the "
                    "machine file's limits (A, B, C in degrees) and servo period, HAL for "
                    "the G-code path (joints looped back as in LinuxCNC's sims; the machine's "
                    "kinematics module with its offsets on the LinuxCNC trunnion types, "
                    "trivkins otherwise) and for the halstreamer stream, and a headless "
                    "display. An existing folder is replaced only if it holds such a "
                    "configuration.")
    _add_machine_options(lcnc, required=True, controller=None)
    lcnc.add_argument("--drives", choices=("looped", "simulated"), default="looped",
                      help="looped: each joint's command looped back as its feedback (LinuxCNC's "
                           "sims: timing only); simulated: each joint closed through LinuxCNC's "
                           "pid (the --controller's gains) around a drive plant of the machine "
                           "file's J, B, ka, kt, rg and Coulomb friction, its actual positions "
                           "recorded (default looped)")
    lcnc.add_argument("--controller", default=None,
                      help="with --drives simulated: the pid controller of the machine file "
                           "whose gains LinuxCNC's pid runs (a tf controller: its base)")
    _add_output(lcnc, metavar="DIR", help="configuration folder")
    lcnc.set_defaults(run=run_linuxcnc_config)
    record = commands.add_parser(
        "linuxcnc-record", help="run a program on a LinuxCNC configuration and record it",
        description="Run a G-code program headless on a configuration written by "
                    "linuxcnc-config (LinuxCNC 2.9 installed here) and write every servo "
                    "period as a servo log: t, the joints' commands, with simulated drives "
                    "their actual positions, and the program line (mm, rad): what identify, "
                    "run --timing and run --learn-from read.")
    record.add_argument("program", type=Path, help="G-code program")
    record.add_argument("--config", type=Path, required=True, metavar="DIR",
                        help="LinuxCNC configuration folder (precontour linuxcnc-config)")
    record.add_argument("--overlay", type=Path, default=None, metavar="FILE",
                        help="a run --overlay file streamed beside the program (its M62 P0 "
                             "starts it); the log's commands are then motion's plus the "
                             "overlay")
    _add_machine_options(record, required=True, controller=None)
    _add_output(record, help="servo log (.csv/.npz/.parquet)")
    record.set_defaults(run=run_linuxcnc_record)


def _machines_epilog() -> str:
    """The built-in machines and their controllers, for the help of run and export."""
    entries = [f"{m.name} ({m.kinematics}, axes {''.join(m.axes)}; controllers "
               f"{', '.join(name for name, _ in m.controllers)})" for m in builtin_machines()]
    return ("Built-in machines (--machine NAME): " + "; ".join(entries) + ". A machine file "
            "names its own controllers. `precontour machines` lists the built-in machines; "
            "`precontour machines --template TYPE` prints a machine file to start from.")


def _add_machine_options(parser: argparse.ArgumentParser, *, required: bool = False,
                         controller: object = DEFAULT_CONTROLLER,
                         machine_help: str = "built-in machine name or machine TOML file"
                         ) -> None:
    """``--machine`` and ``--controller``, declared here for every command.

    ``required``: no default machine. ``run`` and ``export`` write programs for a machine, so
    a machine the user did not name would be wrong silently. ``controller``: the default
    controller name; :data:`REQUIRED` for none; ``""`` for an optional name (``export``
    records it); ``None`` for no ``--controller`` option."""
    hint = "`precontour machines` lists the built-in ones"
    parser.add_argument("--machine", required=required,
                        default=None if required else DEFAULT_MACHINE,
                        help=f"{machine_help} (required; {hint})" if required else
                             f"{machine_help} (default: {DEFAULT_MACHINE})")
    if controller is None:
        return
    if controller is REQUIRED:
        parser.add_argument("--controller", required=True,
                            help=f"controller name in the machine file (required; {hint} "
                                 "with their controllers)")
    elif controller == "":
        parser.add_argument("--controller", default="",
                            help="controller name to record in the header (optional)")
    else:
        parser.add_argument("--controller", default=controller,
                            help=f"controller name in the machine file (default: {controller})")


def _add_toolpath_format_option(parser: argparse.ArgumentParser) -> None:
    """``--format`` and ``--tool-table`` of the commands that read a tool path (trajectory,
    run): the library's ``read_toolpath(format=..., tool_table=...)``."""
    parser.add_argument("--format", choices=TOOLPATH_FORMATS, default=None,
                        help="format of the tool path file: clcsv (CL-data CSV), apt (APT CL "
                             "data), gcode or heidenhain (TNC conversational) (default: from "
                             "its extension; needed for .txt and other extensions)")
    parser.add_argument("--tool-table", type=Path, default=None, metavar="FILE",
                        help="G-code: tool lengths from a LinuxCNC tool table (.tbl, Z in "
                             "mm), applied at G43 H, G43.4 H, G234 H (default: the machine "
                             "file's [tools])")


def _add_output(parser: argparse.ArgumentParser, *, help: str, metavar: str | None = None
                ) -> None:
    """``-o/--output``, which every command that writes has, required."""
    parser.add_argument("-o", "--output", type=Path, required=True, metavar=metavar, help=help)


#: The help of ``--iterations`` where nothing more needs saying.
ITERATIONS_HELP = "largest number of compensation passes (default 1)"


def _add_iterations_option(parser: argparse.ArgumentParser, *,
                           help: str = ITERATIONS_HELP) -> None:
    """``--iterations N`` (>= 1, default 1) of compensate, demo, compare and run."""
    parser.add_argument("--iterations", type=_positive_int, default=1, metavar="N", help=help)


def _add_learn_option(parser: argparse.ArgumentParser, default: int, *, help: str) -> None:
    """``--learn N`` (passes of learning, >= 0) of compensate and run; their defaults differ
    (run's learning costs a program's worth of virtual-machine runs per pass)."""
    parser.add_argument("--learn", type=_nonnegative_int, default=default, metavar="N",
                        help=help)


#: The positional trajectory of compensate and compare: the axes and their reference.
TRAJECTORY_HELP = ("trajectory file with t,X,Y,Z,A,C and the reference Px,Py,Pz,Oi,Oj,Ok")


def _add_planning_options(parser: argparse.ArgumentParser) -> None:
    """The options of planning a trajectory from a program, shared by trajectory and run."""
    parser.add_argument("--tcp", action="store_true",
                        help="G-code: the program starts in tool centre point mode (X Y Z "
                             "the tool tip, A C the rotary axes), for controllers that switch "
                             "it with an M code the machine file's [gcode] tcp_on does not "
                             "name; the TCP-off M code ([gcode] tcp_off, default M429) still "
                             "ends it, G49 and TRAFOOF do not")
    parser.add_argument("--dwell", type=_nonnegative_float, default=DEFAULT_DWELL, metavar="S",
                        help="hold the final position (and, for G-code, each M0/M1/M6 stop) "
                             "this long so the drives settle inside the trajectory "
                             f"(default {DEFAULT_DWELL:g} s)")
    parser.add_argument("--corner-tol", type=_positive_float, default=DEFAULT_CORNER_TOLERANCE,
                        metavar="MM",
                        help="G-code: largest distance by which the blend of a corner between "
                             "two blocks may leave the programmed path, where the program sets "
                             "none (G64 P, G61); sharper corners are slowed for, or stopped at "
                             f"(default {DEFAULT_CORNER_TOLERANCE:g} mm)")
    parser.add_argument("--corner-ori-tol", type=_positive_float,
                        default=DEFAULT_CORNER_ORIENTATION_TOLERANCE, metavar="RAD",
                        help="G-code: largest angle between the tool orientation and the "
                             "programmed one where the blend of a corner passes within "
                             "--corner-tol of it (the corner is passed as a pose, so a rotation "
                             "does not start before the tip is there); corners that need it are "
                             "slowed for, or stopped at (default "
                             f"{DEFAULT_CORNER_ORIENTATION_TOLERANCE:g} rad, the rotary "
                             "decimation tolerance of --tol)")
    parser.add_argument("--max-samples", type=_positive_int, default=None, metavar="N",
                        help="refuse a trajectory of more samples, estimated before any is "
                             "made (default: sized to this machine's memory, "
                             f"{default_max_samples()} here)")


def _add_report_option(parser: argparse.ArgumentParser, default: Path | None = None, *,
                       help: str | None = None) -> None:
    """``--report DIR``: the report folder of demo and compare (``default``; ``--out`` is its
    old spelling, kept), or the optional one of identify and run (no default; ``help`` says
    what goes in it)."""
    if default is None:
        parser.add_argument("--report", type=Path, default=None, metavar="DIR", help=help)
        return
    parser.add_argument("--report", "--out", dest="report", type=Path, default=default,
                        metavar="DIR",
                        help=f"report folder, created if missing (default: {default}; --out "
                             "is the same option)")


def _add_tol_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tol", type=_tolerance, default=None, metavar="MM[,RAD]",
                        help="G-code decimation tolerance per axis: mm on X Y Z and rad on A C "
                             f"(default {GCODE_TOL_LINEAR:g},{GCODE_TOL_ROTARY:g}); the "
                             "blocks, interpolated linearly in time, stay this close to every "
                             "command sample")


def _tolerance(text: str):
    from .toolpath.writers import gcode_tolerances

    parts = text.split(",")
    if len(parts) > 2:
        raise argparse.ArgumentTypeError(f"give MM or MM,RAD, got {text!r}")
    values = [_positive_float(p.strip()) for p in parts]
    linear = values[0]
    rotary = values[1] if len(values) == 2 else GCODE_TOL_ROTARY
    try:
        return gcode_tolerances(linear, rotary)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _add_fit_options(parser: argparse.ArgumentParser, linear: float = FIT_TOL_LINEAR,
                     rotary: float = FIT_TOL_ROTARY) -> None:
    parser.add_argument("--tol-linear", type=_positive_float, default=linear,
                        metavar="MM", help=f"spline fit tolerance of X, Y, Z in mm (default {linear:g})")
    parser.add_argument("--tol-rotary", type=_positive_float, default=rotary,
                        metavar="RAD", help=f"spline fit tolerance of A, C in rad (default {rotary:g})")


def _number(text: str, *, allow_zero: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and (value > 0 or (allow_zero and value == 0))):
        kind = "number >= 0" if allow_zero else "positive number"
        raise argparse.ArgumentTypeError(f"must be a {kind}, got {text!r}")
    return value


def _contour_tolerance(text: str) -> tuple[float, float | None]:
    """``TIP_UM[,ORI_MRAD]`` -> (tip um, orientation mrad or None)."""
    parts = text.split(",")
    if len(parts) > 2:
        raise argparse.ArgumentTypeError(f"give TIP_UM or TIP_UM,ORI_MRAD, got {text!r}")
    values = [_positive_float(p.strip()) for p in parts]
    return values[0], (values[1] if len(values) > 1 else None)


def _speed_fraction(text: str) -> float:
    value = _number(text, allow_zero=False)
    if value > 1.0:
        raise argparse.ArgumentTypeError(f"must be a fraction in (0, 1], got {text!r}")
    return value


def _add_min_speed_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--min-speed", type=_speed_fraction, default=DEFAULT_MIN_SPEED,
                        metavar="FRACTION",
                        help="lowest speed, as a fraction of the planned speed, to which the "
                             "motion is slowed locally to keep the machine's limits; where "
                             "keeping them would need slower, the compensation there is left "
                             "out (the planned commands, tapered in and out) and said so; 1 = "
                             f"never slowed (default {DEFAULT_MIN_SPEED:g})")


def _positive_float(text: str) -> float:
    return _number(text, allow_zero=False)


def _nonnegative_float(text: str) -> float:
    return _number(text, allow_zero=True)


def _whole_number(text: str, *, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {text!r}")
    return value


def _nonnegative_int(text: str) -> int:
    return _whole_number(text, minimum=0)


def _positive_int(text: str) -> int:
    return _whole_number(text, minimum=1)


def run_predict(args: argparse.Namespace) -> int:
    from .compensation.pieces import predict_program
    from .machine.machine_file import load_machine
    from .tables import (COMMAND_TOLERANCE, check_output_table, read_trajectory,
                         write_columns)

    start = time.perf_counter()
    inputs = input_files(args.trajectory, args.machine)
    check_output_table(args.output, inputs)
    machine = load_machine(args.machine)
    models = machine.controller(args.controller).error_models(machine.drives)
    # commands (e.g. pre-compensated ones) are measured against their own reference columns
    traj = read_trajectory(args.trajectory, kinematics=machine.kinematics,
                           tolerance=COMMAND_TOLERANCE)
    # long programs are predicted in pieces (bounded memory; compensation/pieces.py)
    with _about(args.trajectory):
        prediction = predict_program(traj, models, machine.kinematics,
                                     tol_linear=args.tol_linear, tol_rotary=args.tol_rotary)
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
    from .machine.machine_file import load_machine
    from .tables import check_output_table, trajectory_columns, write_columns
    from .toolpath import PROGRAM_FORMATS, read_program, read_toolpath, toolpath_format
    from .trajectory.builtin_paths import builtin_path
    from .trajectory.generate import generate_trajectory, summarize, unfed_notice
    from .trajectory.program import program_trajectory

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
            from .errors import notice
            notice(said)
    if toolpath is not None:
        traj = generate_trajectory(toolpath, machine, feed=args.feed, ts=ts, dwell=args.dwell,
                                   max_samples=args.max_samples)
    write_columns(args.output, trajectory_columns(traj, machine.axis_names), inputs=inputs)
    print(summarize(traj, machine).format())
    print(f"wrote {args.output} in {time.perf_counter() - start:.3f} s")
    return 0


def run_compensate(args: argparse.Namespace) -> int:
    from .options import LearningOptions, LimitOptions
    from .system import compensate, load_servo
    from .tables import check_output_table, read_trajectory, trajectory_columns, write_columns

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
    from .machine.machine_file import load_machine
    from .prediction.contour import ReferencePath, contour_errors
    from .simulation.virtual_machine import simulate
    from .tables import (COMMAND_TOLERANCE, check_output_table, check_reference,
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
    from .reports.demo_report import MACHINE_LABELS, format_table, run_demo as demo_run
    from .reports.progress import ProgressLine

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
    from .reports.compare_report import format_contour_table, run_compare as compare_run
    from .reports.progress import ProgressLine

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
    from .identification import identify, parse_column_map, read_servo_log
    from .machine.machine_file import load_machine, machine_data
    from .tables import write_text

    start = time.perf_counter()
    inputs = input_files(args.log, args.machine)
    outputs = OutputSet(inputs)   # the machine file and the report: checked now, written as one
    outputs.file(args.output)
    base = load_machine(args.machine)
    if args.report is not None:
        from .reports.identify_report import identify_report_files
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
            from .reports.identify_report import write_identify_report
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
    from .identification import excitation_trajectory, write_excitation
    from .identification.excitation import check_excitation_output
    from .machine.drives import AXES, ROTARY_AXES
    from .machine.machine_file import load_machine

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
        from .errors import notice

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
    from .workflow import export_commands

    start = time.perf_counter()
    result = export_commands(args.commands, args.output, format=args.format,
                             machine=args.machine, controller=args.controller,
                             tolerance=args.tol)
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
    from .options import LimitOptions, ToleranceOptions
    from .planning import ContourTolerance
    from .reports.progress import ProgressLine
    from .workflow import RunOutputs, run_program, write_run_outputs

    start = time.perf_counter()
    report_files = ()
    if args.report is not None:
        from .reports.run_report import run_report_files
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
                             iterations=args.iterations, tolerance=args.tol,
                             progress=progress, workers=1, learn=args.learn,
                             limits=LimitOptions(min_speed=args.min_speed),
                             contour_tolerance=feed, draws=args.draws, format=args.format,
                             tool_table=args.tool_table)
        files = []
        # -o, --stream, --commands and the report replace the old files together, or none
        with outputs.output_set(inputs):
            if args.report is not None:
                from .reports.run_report import write_run_report
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
    from .batch import run_batch
    from .options import LimitOptions

    def progress(done: int, total: int, message: str) -> None:
        print(f"[{done}/{total}] {message}", flush=True)

    result = run_batch(args.programs, args.out_dir, machines=args.machine,
                       controller=args.controller, stream=args.stream, commands=args.commands,
                       executor=args.executor, jobs=args.jobs, progress=progress,
                       tcp=args.tcp, dwell=args.dwell, corner_tolerance=args.corner_tol,
                       corner_orientation_tolerance=args.corner_ori_tol,
                       max_samples=args.max_samples, iterations=args.iterations,
                       tolerance=args.tol, learn=args.learn,
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
    from .cnc.run import run_at_timing
    from .system import load_servo

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
        from .machine.template import machine_template
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
    from .machine.machine_file import load_machine
    from .linuxcnc.config import check_config_folder, write_linuxcnc_config

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
    from .cnc.run import record_on_linuxcnc

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
