"""`precontour run --tolerance` measured: write the sections of docs/feed.md.

Two sections, each rewritten by its own run (``--sections``), each stamped:

``paths``
    The built-in paths and the test paths ``fan25`` and ``flank`` of
    ``measure_compensation.py``, written as CL data and run as
    ``precontour run PATH.csv --machine zhang2013 --controller C --tolerance 10`` (both PIDs,
    at the programmed feed and at up to 2 x it): the cycle times as programmed, of the
    uncompensated baseline within the tolerance and compensated within it, the worst errors
    of each on the realistic virtual machine's draws, the rounds and the time taken.
``linuxcnc``
    LinuxCNC's trunnion-table example programs (``impeller-7bl-xyzac.ngc``,
    ``boat-xyzac.ngc``; searched where LinuxCNC installs its examples, or ``--demos DIR``) run
    as ``precontour run PROGRAM --tcp --machine linuxcnc-xyzac-trt --controller pid-high
    --tolerance 5,0.05 --write-anyway`` (``--programs`` picks them; each takes tens of
    minutes).

Run from the repository root:

    python scripts/measure_feed.py [--sections paths,linuxcnc] [--programs boat-xyzac.ngc]
                                   [--demos DIR] [--output docs/feed.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from docpage import DOCS, markdown_table, replace_section, stamp
from measure_compensation import TEST_PATHS, fan25_path, flank_path
from measure_programs import PROGRAMS, find_demo, write_cl_csv
from precontour import builtin_path
from precontour.options import ToleranceOptions
from precontour.planning import ContourTolerance
from precontour.trajectory.builtin_paths import BUILTIN_PATHS
from precontour.workflow import RunOutputs, run_program

CONTROLLERS = ("pid-low", "pid-high")
SCALES = (1.0, 2.0)


def _variant(search) -> str:
    """``12.118 s, 9.83 um`` (and ``/ 0.105 mrad`` where bounded), bold-less, NOT MET flagged."""
    text = (f"{search.duration:,.3f} s, {1e3 * search.errors.tip.max():.2f} um / "
            f"{1e3 * search.errors.orientation.max():.3f} mrad")
    return text if search.met else f"{text} (**not met**)"


def _row(name, controller, scale, result, took):
    feed = result.feed
    return [name, controller, f"{scale:g}", f"{feed.programmed.duration:,.3f} s",
            _variant(feed.baseline), _variant(feed.compensated),
            f"{100 * (1 - feed.ratio):.1f} %", f"{feed.baseline.rounds} / {feed.compensated.rounds}",
            f"{took:.0f} s"]


HEADER = ["path", "controller", "feed scale max", "as programmed", "uncompensated within "
          "tolerance (cycle, worst tip / orientation)", "compensated within tolerance",
          "compensated shorter by", "rounds (uncomp. / comp.)", "took"]


def paths_section(folder: Path) -> str:
    toolpaths = {name: (lambda name=name: builtin_path(name)) for name in BUILTIN_PATHS}
    toolpaths.update(fan25=fan25_path, flank=flank_path)
    rows = []
    for name, make in toolpaths.items():
        source = write_cl_csv(make(), folder / f"{name}.csv")
        for controller in CONTROLLERS:
            for scale in SCALES:
                start = time.perf_counter()
                result = run_program(source, RunOutputs(program=folder / f"{name}.ngc"),
                                     machine="zhang2013", controller=controller,
                                     contour_tolerance=ToleranceOptions(
                                         ContourTolerance(0.010), feed_scale_max=scale,
                                         write_anyway=True))
                rows.append(_row(f"`{name}`" if name in TEST_PATHS else name, controller,
                                 scale, result, time.perf_counter() - start))
                print(" | ".join(map(str, rows[-1])), file=sys.stderr, flush=True)
    return "\n".join([
        "## Built-in and test paths, 10 um", "", stamp(), "",
        "`precontour run PATH.csv --machine zhang2013 --controller C --tolerance 10 "
        "[--feed-scale-max 2]` on each path as CL data (the built-in paths' feed is 100 mm/s; "
        "at 2 x, the tip acceleration and the axis limits cap most of the gain). Cycle times "
        "and the largest errors on the realistic virtual machine, at each sample the worst of "
        "its 5 draws (friction, J, B, encoder) where the search got that far. *Not met*: "
        "somewhere the tolerance is missed even at the lowest feed (5 % of the programmed), "
        "where slowing down did not lower the error (the search stops slowing there), or at "
        "a stop, which slowing down cannot help (`--learn` can: "
        "[run](run.md#faster-within-a-tolerance---tolerance)). Where the uncompensated "
        "program keeps the tolerance at the upper-bound feed already, the compensated one can "
        "be longer: its corrections are slowed to keep the axis limits (a negative gain).", "",
        markdown_table(HEADER, rows, "lllllllll")])


def linuxcnc_section(demos: Path | None, programs: list[str], folder: Path) -> str:
    rows, places = [], []
    for name in programs:
        path = find_demo(name, demos)
        if path is None:
            print(f"not found: {name}", file=sys.stderr)
            continue
        # a plain run first, timed on the same computer in the same run: what the search
        # costs, in plain runs (issue 25: at most 10 on the impeller)
        start = time.perf_counter()
        run_program(path, RunOutputs(program=folder / f"{path.stem}-plain.ngc"),
                    machine="linuxcnc-xyzac-trt", controller="pid-high", tcp=True)
        plain = time.perf_counter() - start
        start = time.perf_counter()
        result = run_program(path, RunOutputs(program=folder / f"{path.stem}-fast.ngc"),
                             machine="linuxcnc-xyzac-trt", controller="pid-high", tcp=True,
                             contour_tolerance=ToleranceOptions(
                                 ContourTolerance(0.005, 5e-5), write_anyway=True))
        took = time.perf_counter() - start
        rows.append(_row(f"`{path.name}`", "pid-high", 1.0, result, took)
                    + [f"{plain:.0f} s", f"{took / plain:.1f}"])
        print(" | ".join(map(str, rows[-1])), file=sys.stderr, flush=True)
        for search, label in ((result.feed.baseline, "uncompensated"),
                              (result.feed.compensated, "compensated")):
            if not search.met:
                places.append(f"- `{path.name}`, {label}: not met in {len(search.misses)} "
                              "place(s), the worst: " + "; ".join(m.format()
                                                                 for m in search.misses[:3]))
    return "\n".join([
        "## LinuxCNC's trunnion-table examples, 5 um / 0.05 mrad", "", stamp(), "",
        "`precontour run PROGRAM --tcp --machine linuxcnc-xyzac-trt --controller pid-high "
        "--tolerance 5,0.05 --write-anyway` (the programmed feed the upper bound; the "
        "rapids' errors not counted); \"plain `run` took\": the same `run` without "
        "`--tolerance`, timed just before it, and \"in plain runs\" what the search took in "
        "those. Where a variant misses the tolerance, the worst places are listed below the "
        "table.", "",
        markdown_table(HEADER + ["plain `run` took", "in plain runs"], rows, "lllllllllrr")]
        + ([""] + places if places else []))


INTRO = """# Feed within a tolerance, measured

What `precontour run --tolerance` gains: the fastest motion whose compensated contour errors
keep a tolerance on the realistic virtual machine, against the fastest uncompensated motion
with the same local retiming. Written by `scripts/measure_feed.py`, one section per run of
it, each stamped; do not edit by hand. How it works:
[run](run.md#faster-within-a-tolerance---tolerance)."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sections", default="paths",
                        help="sections to measure: paths, linuxcnc (default paths)")
    parser.add_argument("--programs", default=",".join(PROGRAMS),
                        help=f"LinuxCNC examples to run (default {','.join(PROGRAMS)})")
    parser.add_argument("--demos", type=Path, default=None,
                        help="folder holding LinuxCNC's impeller-7bl-xyzac.ngc and boat-xyzac.ngc")
    parser.add_argument("--output", type=Path, default=DOCS / "feed.md",
                        help="page whose sections are rewritten (default docs/feed.md)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        replace_section(args.output, "intro", INTRO)
        for section in args.sections.split(","):
            if section == "paths":
                body = paths_section(folder)
            elif section == "linuxcnc":
                body = linuxcnc_section(args.demos, args.programs.split(","), folder)
            else:
                parser.error(f"unknown section {section!r}")
            print(f"wrote {replace_section(args.output, section, body)} (section {section})",
                  file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
