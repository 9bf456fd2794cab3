"""Command-line interface: ``precontour <command> ...``.

Each command reads files, calls the pipeline stages and writes files; no numerics live here.
User errors (bad files, values, names) print one line ``precontour: error: ...`` and exit 2.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from . import __version__
from .drives import AXES, ROTARY_AXES
from .errors import PrecontourError
from .machine import load_machine
from .splinefit import DEFAULT_TOL_LINEAR, DEFAULT_TOL_ROTARY
from .tables import read_trajectory, write_columns
from .tracking import predict_tracking

EXIT_USAGE = 2


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        return args.run(args)
    except PrecontourError as exc:
        print(f"precontour: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:  # pragma: no cover - interactive
        print("precontour: interrupted", file=sys.stderr)
        return 130


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="precontour",
        description="Predict and pre-compensate five-axis CNC contour errors "
                    "(Zhang, Yuen & Altintas 2013).")
    parser.add_argument("--version", action="version", version=f"precontour {__version__}")
    commands = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")

    predict = commands.add_parser(
        "predict", help="predict each axis's tracking error in closed form",
        description="Fit each axis command with a minimum-jerk C3 quintic spline and predict "
                    "its tracking error (command minus actual) in closed form.")
    predict.add_argument("trajectory", type=Path,
                         help="trajectory file (.csv/.npz/.parquet) with columns t,X,Y,Z,A,C "
                              "(s, mm, rad), uniformly sampled")
    _add_machine_options(predict)
    _add_fit_options(predict)
    predict.add_argument("-o", "--output", type=Path, required=True,
                         help="output file (.csv/.npz/.parquet): t,eX,eY,eZ,eA,eC")
    predict.set_defaults(run=run_predict)
    return parser


def _add_machine_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--machine", default="zhang2013",
                        help="built-in machine name or machine TOML file (default: zhang2013)")
    parser.add_argument("--controller", default="pid-low",
                        help="controller name in the machine file (default: pid-low)")


def _add_fit_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tol-linear", type=_positive_float, default=DEFAULT_TOL_LINEAR,
                        metavar="MM", help="spline fit tolerance of X, Y, Z in mm "
                                           f"(default {DEFAULT_TOL_LINEAR:g} = 1 um)")
    parser.add_argument("--tol-rotary", type=_positive_float, default=DEFAULT_TOL_ROTARY,
                        metavar="RAD", help="spline fit tolerance of A, C in rad "
                                            f"(default {DEFAULT_TOL_ROTARY:g} = 1 urad)")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0 and np.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def run_predict(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    machine = load_machine(args.machine)
    models = machine.controller(args.controller).error_models(machine.drives)
    traj = read_trajectory(args.trajectory)
    prediction = predict_tracking(traj.t, traj.q, models, tol_linear=args.tol_linear,
                                  tol_rotary=args.tol_rotary)
    e = prediction(traj.t)
    columns = {"t": traj.t}
    columns.update({f"e{axis}": e[:, i] for i, axis in enumerate(AXES)})
    write_columns(args.output, columns, inputs=[args.trajectory])
    elapsed = time.perf_counter() - start
    print(f"predicted tracking errors of {traj.n_samples} samples "
          f"({traj.duration:.3f} s) on {machine.name}, controller {args.controller}")
    print(_axis_table(prediction.fits.n_knots, np.abs(e).max(axis=0)))
    print(f"wrote {args.output} in {elapsed:.3f} s")
    return 0


def _axis_table(knots, max_abs_e) -> str:
    lines = ["axis  knots      max|e|"]
    for axis, n, value in zip(AXES, knots, max_abs_e):
        unit, scale = ("mrad", 1e3) if axis in ROTARY_AXES else ("um", 1e3)
        lines.append(f"{axis:>4}  {n:5d}  {value * scale:10.3f} {unit}")
    return "\n".join(lines)
