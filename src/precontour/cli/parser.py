"""The ``precontour`` commands, their options and the checks of their values (argparse).

Only light modules here: the numerical stack (numpy, scipy, numba, matplotlib, and the
compiled kernels) takes a second or more to load, so each command imports what it needs when
it runs (:mod:`.commands`), and --help, --version and ``machines`` never load it. Defaults and
names the help shows come from :mod:`precontour.defaults` (tests/test_cli.py checks what
--help imports)."""

from __future__ import annotations

import argparse
import math
import textwrap
from pathlib import Path

from .. import __version__
from ..defaults import (BUILTIN_MACHINES, BUILTIN_PATHS, COMPENSATION_METHODS,
                        COMPENSATION_TOL_LINEAR, COMPENSATION_TOL_ROTARY, DEFAULT_CHECK_DRAWS,
                        DEFAULT_CORNER_ORIENTATION_TOLERANCE, DEFAULT_CORNER_TOLERANCE,
                        DEFAULT_DWELL, DEFAULT_FEED, DEFAULT_FEED_SCALE_MAX,
                        DEFAULT_FEED_SCALE_MAX_CL, DEFAULT_FEED_SCALE_MIN, DEFAULT_LEARNING_PASSES,
                        DEFAULT_MIN_SPEED, DEFAULT_SAFETY, DEFAULT_TRAVEL_LINEAR,
                        DEFAULT_TRAVEL_ROTARY, EXPORT_FORMATS, FIT_TOL_LINEAR, FIT_TOL_ROTARY,
                        GCODE_TOL_LINEAR, GCODE_TOL_ROTARY, LOG_FORMATS, TOOLPATH_FORMATS,
                        builtin_machines, default_max_samples)
from ..errors import InputError
from .commands import (run_batch_command, run_compare, run_compensate, run_demo, run_excite,
                       run_export, run_identify, run_linuxcnc_config, run_linuxcnc_record,
                       run_machines, run_predict, run_run, run_simulate, run_trajectory)


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
    from ..toolpath.writers import gcode_tolerances

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
