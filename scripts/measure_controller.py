"""Measure compensation on a real controller's closed loop: the tables of docs/controller.md.

    PYTHONPATH=src python scripts/measure_controller.py [--iterations 3] [--impeller-lines 450]

Needs LinuxCNC 2.9 (linuxcnc-uspace) and, as root, the unprivileged user lcnc. For each case
(LinuxCNC's closed loop of ``precontour linuxcnc-config --drives simulated``: LinuxCNC's pid
with the machine file's pid-high gains around a drive with Coulomb friction):

1. ``excite`` run on LinuxCNC and recorded, ``identify`` on that log;
2. the program run as written (the timing trace) and once more (repeatability);
3. ``run --timing`` (the identified model's compensation in the program's own blocks), run;
4. ``run --timing --learn-from`` the latest run, ``--iterations`` times, each run.

Every error is measured from the actual positions LinuxCNC's loop recorded, with the k-d tree
closest-point code of tests/linuxcnc/closed_loop_measure.py, from 0.3 s after the first move
to the end of the commanded motion; the timing of every block against the uncompensated
run's. The cases: the paper path's G-code (``precontour export`` of the built-in path,
zhang2013, trivial kinematics in LinuxCNC) and the first ``--impeller-lines`` motion lines of
LinuxCNC's impeller (linuxcnc-xyzac-trt, tool centre point with xyzac-trt-kins).
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests" / "linuxcnc"))

from docpage import DOCS, markdown_table, stamp, write_page  # noqa: E402

from precontour import builtin_path, load_machine  # noqa: E402
from precontour.cli import main  # noqa: E402
from precontour.toolpath import read_program  # noqa: E402
from precontour.linuxcnc.run import linuxcnc_unavailable  # noqa: E402

from closed_loop_measure import (SETTLE, errors, late, line_maxima, line_maxima_of,  # noqa: E402
                                 read_log, worse_lines)
from lcnc_fixtures import DEMOS  # noqa: E402

IMPELLER = DEMOS / "impeller-7bl-xyzac.ngc"


def _quiet(argv: list[str]) -> None:
    if main(argv) != 0:
        raise SystemExit(f"failed: precontour {' '.join(argv)}")


def impeller_head(lines: int, out: Path) -> Path:
    """The impeller's first ``lines`` lines with axis words (and what precedes them), then
    M2."""
    kept, count = [], 0
    for line in IMPELLER.read_text().splitlines():
        code = re.sub(r"\([^)]*\)", "", line).split(";")[0].upper()
        if re.match(r"\s*M(2|30)\b", code):
            continue
        kept.append(line)
        if re.search(r"[XYZAC]\s*[-+.0-9]", code):
            count += 1
            if count == lines:
                break
    out.write_text("\n".join(kept + ["M2"]) + "\n")
    return out


def bench_case(name: str, machine_name: str, program: Path, work: Path,
               iterations: int, cl_data: Path | None = None,
               identify: bool = True) -> list[list]:
    machine = load_machine(machine_name)
    letters = "".join(machine.axis_names)
    config = work / "cfg"
    started = time.perf_counter()
    _quiet(["linuxcnc-config", "--machine", machine_name, "--drives", "simulated",
            "--controller", "pid-high", "-o", str(config)])
    if identify:
        _quiet(["excite", "--machine", machine_name, "-o", str(work / "exc.ngc")])
        _quiet(["linuxcnc-record", str(work / "exc.ngc"), "--config", str(config),
                "--machine", machine_name, "-o", str(work / "exc.csv")])
        _quiet(["identify", str(work / "exc.csv"), "--machine", machine_name,
                "-o", str(work / "ident.toml")])
        run = ["run", str(program), "--machine", str(work / "ident.toml"), "--controller",
               "identified"]
    else:   # the machine file's model of the gains LinuxCNC's pid runs
        run = ["run", str(program), "--machine", machine_name, "--controller", "pid-high"]
    moves = read_program(program, machine).programmed

    def record(prog: Path, log: str):
        _quiet(["linuxcnc-record", str(prog), "--config", str(config), "--machine",
                machine_name, "-o", str(work / log)])
        return read_log(work / log, letters)

    _quiet(run + ["--timing", f"linuxcnc:{config}", "--timing-out", str(work / "timing.csv"),
                  "-o", str(work / "predicted.ngc")])
    timing = read_log(work / "timing.csv", letters)
    rows = [("as written", timing), ("as written, again", record(program, "again.csv"))]
    latest = record(work / "predicted.ngc", "run0.csv")
    rows.append(("blocks, predicted (`run --timing`)", latest))
    for k in range(1, iterations + 1):
        _quiet(run + ["--timing", str(work / "timing.csv"), "--learn-from",
                      str(work / f"run{k - 1}.csv"), "--repeat", str(work / "again.csv"),
                      "-o", str(work / f"learned{k}.ngc")])
        latest = record(work / f"learned{k}.ngc", f"run{k}.csv")
        rows.append((f"blocks, `--learn-from` {k}", latest))
    # the overlay: the program as written (M62 P0 on its first move), the correction at the
    # servo rate between motion and the pid
    _quiet(run + ["--timing", str(work / "timing.csv"), "--overlay", str(work / "ov0.txt"),
                  "-o", str(work / "overlaid.ngc")])
    for k in range(iterations + 1):
        if k:
            _quiet(run + ["--timing", str(work / "timing.csv"), "--learn-from",
                          str(work / f"ovrun{k - 1}.csv"), "--repeat", str(work / "again.csv"),
                          "--overlay", str(work / f"ov{k}.txt"),
                          "-o", str(work / "overlaid.ngc")])
        _quiet(["linuxcnc-record", str(work / "overlaid.ngc"), "--overlay",
                str(work / f"ov{k}.txt"), "--config", str(config), "--machine", machine_name,
                "-o", str(work / f"ovrun{k}.csv")])
        rows.append(("overlay, predicted" if k == 0 else f"overlay, `--learn-from` {k}",
                     read_log(work / f"ovrun{k}.csv", letters)))
    base_tip, base_ori = errors(timing, timing, moves, machine.kinematics)
    # lines judged from SETTLE after the first move (as the table) and from the first move
    settles = (SETTLE, 0.0)
    base = [line_maxima_of(timing, timing, moves, machine.kinematics, s) for s in settles]
    again = [line_maxima_of(timing, rows[1][1], moves, machine.kinematics, s)
             for s in settles]
    table = []
    for label, log in rows:
        tip, ori, line = errors(timing, log, moves, machine.kinematics, with_lines=True)
        periods = late(timing, log, moves)
        worse = worse_lines(line_maxima(tip, ori, line), base[0], again[0])
        worse_all = worse_lines(line_maxima_of(timing, log, moves, machine.kinematics, 0.0),
                                base[1], again[1])
        table.append([name, label, f"{tip.max():.2f}", f"{tip.mean():.3f}",
                      f"{100 * tip.mean() / base_tip.mean():.0f} %", f"{ori.max():.3f}",
                      f"{ori.mean():.4f}", f"{np.abs(periods).max()}",
                      f"{int(np.sum(np.abs(periods) > 1))} of {periods.size}",
                      f"{len(worse)} / {len(worse_all)}"])
    if cl_data is not None:
        # run as before --timing: compensated for precontour's own plan, written as new G93
        # blocks, which LinuxCNC re-times (its blocks are not the program's: no block offsets)
        _quiet(["run", str(cl_data), "--machine", machine_name, "--controller", "pid-high",
                "-o", str(work / "own-plan.ngc")])
        log = record(work / "own-plan.ngc", "own-plan.csv")
        own_moves = read_program(work / "own-plan.ngc", machine).programmed
        tip, ori = errors(timing, log, own_moves, machine.kinematics)
        table.append([name, "`run` without `--timing` (its own plan, new G93 blocks; "
                      "machine file's pid-high model)", f"{tip.max():.2f}", f"{tip.mean():.3f}",
                      f"{100 * tip.mean() / base_tip.mean():.0f} %", f"{ori.max():.3f}",
                      f"{ori.mean():.4f}", "–", "–", "–"])
    print(f"  {name}: {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return table


def page(tables: list[list], notes: list[str]) -> str:
    header = ["program", "commands", "tip max µm", "tip mean µm", "mean of uncompensated",
              "ori max mrad", "ori mean mrad", "blocks: largest offset, periods",
              "blocks > 1 period off", "lines worse: from 0.3 s / from the first move"]
    rows = [row for table in tables for row in table]
    return "\n".join([
        "# Measured on LinuxCNC's closed loop",
        "",
        stamp(),
        "",
        "LinuxCNC 2.9 headless, every joint closed through LinuxCNC's `pid` (the machine "
        "file's `pid-high` gains) around a simulated drive with Coulomb friction "
        "(`precontour linuxcnc-config --drives simulated`), 1 ms servo thread. Errors from the "
        "actual positions LinuxCNC recorded, measured by a k-d tree closest-point search of "
        "the tests' own (tests/linuxcnc/closed_loop_measure.py) against the uncompensated "
        "run's commanded path, from 0.3 s after the first move to the end of the commanded "
        "motion. Block offsets: servo periods each block started off the uncompensated run's "
        "(LinuxCNC's `motion.program-line`). Learning: each `--learn-from` iteration learns "
        "from the run of the row above it (`--repeat` the second uncompensated run). Lines "
        "worse: program lines whose tip or orientation max (the same measure, per line) is "
        "above the uncompensated run's by more than 0.1 um / 1 urad or 5 % of it, or than "
        "the line's difference between the two uncompensated runs, counted from 0.3 s after "
        "the first move as the rest of the table, and from the first move. How: "
        "[On a real controller](controller.md).",
        "",
        markdown_table(header, rows, "llrrrrrrrr"),
        "",
        *notes,
        "",
    ])


def main_(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--impeller-lines", type=int, default=450)
    parser.add_argument("--out", type=Path, default=DOCS / "controller-measured.md")
    args = parser.parse_args(argv)
    why = linuxcnc_unavailable()
    if why:
        raise SystemExit(f"needs LinuxCNC: {why}")
    tables: list[list] = []
    notes: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        paper = tmp / "paper"
        paper.mkdir()
        _quiet(["trajectory", "--builtin", "paper", "-o", str(paper / "paper.csv")])
        _quiet(["export", str(paper / "paper.csv"), "--machine", "zhang2013",
                "-o", str(paper / "paper.ngc")])
        cl_data = paper / "paper-cl.csv"
        path = builtin_path("paper")
        np.savetxt(cl_data, np.column_stack([path.P, path.O]), delimiter=",",
                   header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.9f")
        tables.append(bench_case("`paper` G-code (zhang2013, identified)", "zhang2013",
                                 paper / "paper.ngc", paper, args.iterations, cl_data))
        notes.append("- `paper`: the drives identified with `identify` from an `excite` log "
                     "recorded on the loop (every loop fitted within 1.0-6.3 % of max|e|).")
        write_page(args.out, page(tables, notes))      # each case as soon as it is measured
        impeller = tmp / "impeller"
        impeller.mkdir()
        head = impeller_head(args.impeller_lines, impeller / "impeller.ngc")
        tables.append(bench_case(f"impeller, first {args.impeller_lines} motion lines "
                                 "(linuxcnc-xyzac-trt, TCP, machine file's model)",
                                 "linuxcnc-xyzac-trt", head, impeller, args.iterations,
                                 identify=False))
        notes.append("- impeller: the machine file's `pid-high` model of the loop (the gains "
                     "LinuxCNC's pid runs), not identified: on this machine's limits (20 mm/s, "
                     "300 mm/s², A and C 30 deg/s) `excite` moves so slowly that Coulomb "
                     "friction dominates its log, and `identify` fitted X, A and C to 35-55 % "
                     "of max|e| with a pole at -0.5 rad/s (measured on 2026-12-04 from an "
                     "11-minute recording).")
    write_page(args.out, page(tables, notes))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
