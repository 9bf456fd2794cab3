"""`precontour run` on programs, measured: write the sections of docs/programs.md.

Two sections, each rewritten by its own run (``--sections``), each stamped:

``linuxcnc``
    LinuxCNC's public trunnion-table example programs (``impeller-7bl-xyzac.ngc``,
    ``boat-xyzac.ngc`` and ``boat-xyzbc.ngc``, the last as issue 21 measures it, without its
    two closing moves in machine coordinates (G53); searched where LinuxCNC installs its
    examples, or ``--demos DIR``) run as ``precontour run PROGRAM --tcp --machine
    linuxcnc-xyzac-trt`` (``linuxcnc-xyzbc-trt`` for the B-C boat) ``--controller
    pid-high``: planned and compensated duration, slowed windows, kinks smoothed, the
    simulated contour errors before and after, the lines worse than uncompensated, which of
    issue 21's targets for real programs are met and the time ``run`` took; with ``--learn N``
    (default 4) each program also with ``--learn N`` (segment by segment above 500,000
    samples; ``--learn 0`` measures without it only).
``long``
    The same for the 18-minute synthetic CL path of ``benchmarks/bench_run.py`` (a spiral over
    a dome, the tool tilting and turning), ``precontour run PATH.csv --machine zhang2013
    --controller pid-high``.
``learn``
    The built-in paths and the test paths ``fan25`` and ``flank`` of
    ``measure_compensation.py``, written as CL data and run as ``precontour run PATH.csv`` with
    ``--learn 0`` and ``--learn N`` (default 4), both PIDs: reductions of the simulated contour
    errors and what learning kept.

Run from the repository root:

    python scripts/measure_programs.py [--sections linuxcnc,long,learn] [--learn 4]
                                       [--demos DIR]
                                       [--output docs/programs.md]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from docpage import DOCS, markdown_table, replace_section, stamp
from measure_compensation import TEST_PATHS, fan25_path, flank_path
from precontour import builtin_path
from precontour.trajectory.builtin_paths import BUILTIN_PATHS
from precontour.workflow import RunOutputs, run_program

#: Where LinuxCNC installs the trunnion-table demos (Debian packages, then a source tree).
DEMO_FOLDERS = (
    "/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
    "table-rotary-tilting/demos",
    "/usr/share/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
    "table-rotary-tilting/demos",
)
PROGRAMS = ("impeller-7bl-xyzac.ngc", "boat-xyzac.ngc")
#: The B-C table's example, on its machine; run without its closing G53 moves.
BC_PROGRAM, BC_MACHINE = "boat-xyzbc.ngc", "linuxcnc-xyzbc-trt"
#: Minutes of motion of the synthetic path of the ``long`` section (issue 21's 18-minute path).
LONG_MINUTES = 18.0
#: Issue 21's targets for real programs with ``run``: at least these shares (%) of the max
#: and mean tip error removed on the worst draw, at most this added time (%), no window slower
#: than this fraction of the planned speed, and no line worse than uncompensated.
REAL_MAX, REAL_MEAN, REAL_TIME, REAL_FLOOR = 80.0, 95.0, 5.0, 0.5
CONTROLLERS = ("pid-high", "pid-low")
#: What the learn section counts, in % of the uncompensated tip error removed on the worst
#: draw: the targets of issue 21 on the built-in and test paths.
TARGET_MAX, TARGET_MEAN = 85.0, 95.0


def find_demo(name: str, demos: Path | None = None) -> Path | None:
    """LinuxCNC's example program ``name``: in ``demos`` if given, else where LinuxCNC
    installs its examples (:data:`DEMO_FOLDERS`); None where it is in neither."""
    candidates = ([demos / name] if demos else []) + [Path(d) / name for d in DEMO_FOLDERS]
    return next((c for c in candidates if c.is_file()), None)


def reduction(before: float, after: float) -> float:
    return 100 * (1 - after / before)


def summary_pair(result) -> tuple[dict, dict]:
    return result.simulated_before.summary(), result.simulated_after.summary()


def without_g53(path: Path, folder: Path) -> Path:
    """A copy of ``path`` in ``folder`` without its moves in machine coordinates (G53) and
    what follows them (the B-C boat's last two moves, before its closing M codes)."""
    kept = []
    for line in path.read_text(errors="replace").splitlines():
        code = re.sub(r"\([^)]*\)", "", line).split(";")[0].upper()
        if re.search(r"G0*53(?![0-9.])", code):
            break
        kept.append(line)
    out = folder / path.name
    out.write_text("\n".join(kept + ["M30"]) + "\n")
    return out


def program_rows(runs, folder: Path) -> tuple[list, list]:
    """Table rows and "where" lines of ``run`` on each ``(label, path, learn, options)``."""
    rows, places = [], []
    for label, path, learn, options in runs:
        start = time.perf_counter()
        result = run_program(path, RunOutputs(program=folder / f"{path.stem}-comp.ngc"),
                             learn=learn, **options)
        took = time.perf_counter() - start
        before, after = summary_pair(result)
        planned, final = result.planned.duration, result.commands.duration
        rows.append([
            label, str(learn),
            f"{planned:,.0f} s", f"{final:,.0f} s ({100 * (final / planned - 1):+.1f} %)",
            len(result.limited.slowdowns), len(result.limited.kinks),
            len(result.limited.smoothed),
            f"{before['tip_max_um']:.3g} → {after['tip_max_um']:.3g}",
            f"{before['tip_mean_um']:.3g} → {after['tip_mean_um']:.3g}",
            f"{before['ori_max_mrad']:.3g} → {after['ori_max_mrad']:.3g}",
            len(result.worse_lines()), *draw_cells(result), targets_met(result),
            f"{result.commands.n_samples:,}", f"{took:.0f} s"])
        # where the largest remaining tip error is, and what the uncompensated command had there
        i = int(np.argmax(result.simulated_after.tip))
        line = result.limited.line
        where = "row" if path.suffix.lower() == ".csv" else "line"
        places.append(f"- {label} (`--learn {learn}`): the largest remaining tip error, "
                      f"{1e3 * result.simulated_after.tip[i]:.3g} um, is at t = "
                      f"{result.commands.t[i]:.3f} s"
                      + (f", {where} {int(line[i])}" if line is not None else "")
                      + f"; the uncompensated command had "
                      f"{1e3 * result.simulated_before.tip[i]:.3g} um there.")
    return rows, places


#: The columns of the program tables (``program_rows``).
PROGRAM_COLUMNS = ["program", "`--learn`", "planned", "after `run`", "windows slowed",
                   "kinks smoothed", "smoothed instead of slowed", "tip max, um",
                   "tip mean, um", "orientation max, mrad", "lines worse",
                   "worst draw: tip max, um", "removed, median / worst",
                   "lines worse, worst draw", "rerun worse than itself",
                   "issue 21's targets met", "samples", "took"]
PROGRAM_ALIGN = "lrrrrrrlllrllrrlrr"
#: What the program tables' columns mean.
PROGRAM_LEGEND = (
    "Contour errors on the realistic virtual machine, before = the uncompensated commands on "
    "the same timing. \"worst draw\": of the machine file's machine and `run`'s four draws of "
    "it (`--draws 5`: friction +-2 %, J and B +-1 %, a noisy 10 nm encoder), the largest tip "
    "error, the smallest share of it removed, and the lines where the compensated commands' "
    "worst draw is worse than the uncompensated commands' beyond 0.1 um / 1 urad or 5 % and "
    "the line's repeatability (in brackets: by the margins alone); \"rerun worse than "
    "itself\": the lines where the uncompensated commands, run again on the same machines "
    "with their encoder noise drawn afresh, are worse than their first run by the margins "
    "alone, what no command decides. \"issue 21's targets met\": of its five for real "
    f"programs (worst draw: at least {REAL_MAX:g} % of the max and {REAL_MEAN:g} % of the "
    f"mean tip error removed, no line worse; at most {REAL_TIME:g} % added time; no window "
    f"slower than {100 * REAL_FLOOR:g} % of the planned speed), those met. \"took\" is the "
    "whole `run`, G-code and draws included, on the computer of the stamp.")


def targets_met(result) -> str:
    """Which of issue 21's five targets for real programs ``result`` meets (worst draw)."""
    check = result.draws
    met = {
        "max": 100 * check.reductions("tip_max").min() >= REAL_MAX,
        "mean": 100 * check.reductions("tip_mean").min() >= REAL_MEAN,
        "no line worse": check.worse_blocks().size == 0,
        "time": 100 * (result.commands.duration / result.planned.duration - 1) <= REAL_TIME,
        "floor": min((s.speed for s in result.limited.slowdowns), default=1.0) >= REAL_FLOOR,
    }
    names = [name for name, ok in met.items() if ok]
    return f"{len(names)} of 5" + (f": {', '.join(names)}" if names else "")


def linuxcnc_section(demos: Path | None, folder: Path, passes: int = 0) -> str:
    runs = []
    found = [(name, "linuxcnc-xyzac-trt") for name in PROGRAMS] + [(BC_PROGRAM, BC_MACHINE)]
    for name, machine in found:
        path = find_demo(name, demos)
        if path is None:
            continue
        label = f"`{path.name}` ({len(path.read_text(errors='replace').splitlines()):,} lines)"
        if name == BC_PROGRAM:
            path = without_g53(path, folder)
            label = (f"`{name}` without its G53 moves "
                     f"({len(path.read_text().splitlines()):,} lines)")
        runs += [(label, path, learn, dict(machine=machine, controller="pid-high", tcp=True))
                 for learn in sorted({0, passes})]
    rows, places = program_rows(runs, folder)
    lines = ["## LinuxCNC's example programs", "", stamp(), "",
             "`precontour run PROGRAM --tcp --machine linuxcnc-xyzac-trt --controller pid-high "
             "-o OUT.ngc` (`--machine linuxcnc-xyzbc-trt` for the B-C boat). " + PROGRAM_LEGEND,
             ""]
    if not rows:
        lines.append("LinuxCNC's example programs were not found (`--demos DIR`).")
    else:
        lines.append(markdown_table(PROGRAM_COLUMNS, rows, PROGRAM_ALIGN))
        lines += [""] + places
    return "\n".join(lines)


def long_section(folder: Path, passes: int = 0) -> str:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_run import SECONDS_PER_POINT
    from bench_trajectory import synthetic_path

    n_points = int(round(LONG_MINUTES * 60.0 / SECONDS_PER_POINT))
    # written as bench_run.py writes it (9 decimals)
    source = write_cl_csv(synthetic_path(n_points), folder / "synthetic.csv", fmt="%.9f")
    label = f"synthetic path ({n_points:,} CL points)"
    runs = [(label, source, learn, dict(machine="zhang2013", controller="pid-high"))
            for learn in sorted({0, passes})]
    rows, places = program_rows(runs, folder)
    return "\n".join([
        f"## The {LONG_MINUTES:g}-minute synthetic path", "", stamp(), "",
        "`precontour run synthetic.csv --machine zhang2013 --controller pid-high -o OUT.ngc` "
        "on the CL path of `benchmarks/bench_run.py` (a spiral over a dome, the tool tilting "
        "and turning; C reverses thrice a turn), its rows the lines. " + PROGRAM_LEGEND, "",
        markdown_table(PROGRAM_COLUMNS, rows, PROGRAM_ALIGN), "", *places])


def draw_cells(result) -> list[str]:
    """The worst draw's tip max before -> after, the median / worst share removed, the lines
    worse on the worst draw beyond the margins and the line's repeatability (by the margins
    alone), and the lines where the uncompensated commands run again are worse than
    themselves (``run``'s check on its draws)."""
    check = result.draws
    worst = [max(s["tip_max_um"] for s in j.summaries) for j in (check.before, check.after)]
    removed = 100 * check.reductions("tip_max")
    return [f"{worst[0]:.3g} → {worst[1]:.3g}",
            f"{np.median(removed):.1f} / {removed.min():.1f} %",
            f"{check.worse_blocks().size:,} ({check.worse_blocks_without_repeatability().size:,})",
            f"{check.self_worse_blocks().size:,}"]


def write_cl_csv(toolpath, path: Path, fmt: str = "%.17g") -> Path:
    """A tool path as CL data (``Px,Py,Pz,Oi,Oj,Ok``; by default 17 digits: the points as
    they are)."""
    np.savetxt(path, np.column_stack([toolpath.P, toolpath.O]), delimiter=",",
               header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt=fmt)
    return path


def learn_section(passes: int, folder: Path) -> str:
    toolpaths = {name: (lambda name=name: builtin_path(name)) for name in BUILTIN_PATHS}
    toolpaths.update(fan25=fan25_path, flank=flank_path)
    rows = []
    met = 0
    for name, make in toolpaths.items():
        source = write_cl_csv(make(), folder / f"{name}.csv")
        for controller in CONTROLLERS:
            cells = []
            for learn in (0, passes):
                result = run_program(source, RunOutputs(program=folder / f"{name}.ngc"),
                                     machine="zhang2013", controller=controller, learn=learn)
                before, after = summary_pair(result)
                cells.append(f"{reduction(before['tip_max_um'], after['tip_max_um']):.1f} / "
                             f"{reduction(before['tip_mean_um'], after['tip_mean_um']):.1f}, "
                             f"{reduction(before['ori_max_mrad'], after['ori_max_mrad']):.1f} / "
                             f"{reduction(before['ori_mean_mrad'], after['ori_mean_mrad']):.1f}")
                learning = result.limited.result.learning
                slowed = len(result.limited.slowdowns)
            cells[-1] = f"**{cells[-1]}**"
            # the last run's (with learning) draws: median and worst share removed, rows worse
            check = result.draws
            removed = {key: 100 * check.reductions(key) for key in ("tip_max", "tip_mean")}
            worse = check.worse_blocks().size
            met += (removed["tip_max"].min() >= TARGET_MAX and
                    removed["tip_mean"].min() >= TARGET_MEAN and worse == 0)
            draws = (f"{np.median(removed['tip_max']):.1f} / {removed['tip_max'].min():.1f}, "
                     f"{np.median(removed['tip_mean']):.1f} / {removed['tip_mean'].min():.1f}")
            rows.append([f"`{name}`" if name in TEST_PATHS else name, controller, *cells,
                         draws, worse, learning.chosen if learning is not None else "-",
                         slowed])
    return "\n".join([
        "## `run --learn` on the built-in and test paths", "", stamp(), "",
        "`precontour run PATH.csv --machine zhang2013 --controller C` on each path as CL "
        "data, with `--learn 0` (the default) and with "
        f"`--learn {passes}` ([learning within the limits](run.md#learning-within-the-limits---learn)). "
        "Reductions of the max / mean contour errors on the realistic virtual machine, tip then "
        "orientation, in %. Where `run` slows a window down or smooths a kink to keep the "
        "limits, its errors differ from those of `compensate` "
        "([compensation, measured](compensation.md)). Where friction holds the axes at a stop is "
        "decided by nanometres, so these numbers move by a few points with the input's last "
        "digits. \"draws\": with learning, the tip error's max then mean removed over `run`'s "
        "five draws of the machine (`--draws 5`: the machine file's machine, and four with "
        "friction +-2 %, J and B +-1 %, a noisy 10 nm encoder), median / worst draw, and the "
        "rows where the worst draw is worse than the uncompensated commands' beyond 0.1 um / "
        "1 urad or 5 % and the row's repeatability.", "",
        markdown_table(["path", "controller", "`--learn 0`", f"`--learn {passes}`",
                        f"`--learn {passes}`, draws: tip max; mean, median / worst",
                        "rows worse, worst draw", "learning kept",
                        "windows slowed (with learning)"], rows, "lllllrll"),
        "", f"With learning, {met} of {len(rows)} remove at least {TARGET_MAX:g} % of the max "
            f"and {TARGET_MEAN:g} % of the mean tip error on the worst draw with no row worse."])


INTRO = """# Programs, measured

What `precontour run` does to whole programs: how much it slows them to keep the machine's
limits, and the contour errors before and after on the realistic virtual machine. Written by
`scripts/measure_programs.py`, one section per run of it, each stamped; do not edit by hand.
How `run` works: [run](run.md). The speed of `run` on long programs: [speed](speed.md)."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sections", default="linuxcnc,long,learn",
                        help="sections to measure (default linuxcnc,long,learn)")
    parser.add_argument("--learn", type=int, default=4, help="learning passes (default 4)")
    parser.add_argument("--demos", type=Path, default=None,
                        help="folder holding LinuxCNC's impeller-7bl-xyzac.ngc and boat-xyzac.ngc")
    parser.add_argument("--output", type=Path, default=DOCS / "programs.md",
                        help="page whose sections are rewritten (default docs/programs.md)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        replace_section(args.output, "intro", INTRO)
        for section in args.sections.split(","):
            if section == "linuxcnc":
                body = linuxcnc_section(args.demos, folder, args.learn)
            elif section == "long":
                body = long_section(folder, args.learn)
            elif section == "learn":
                body = learn_section(args.learn, folder)
            else:
                parser.error(f"unknown section {section!r}")
            print(f"wrote {replace_section(args.output, section, body)} (section {section})",
                  file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
