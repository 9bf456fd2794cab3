"""Measure run's outputs on LinuxCNC itself: the tables of docs/linuxcnc.md.

    PYTHONPATH=src python scripts/measure_linuxcnc.py [--long] [--out DIR]

Needs LinuxCNC 2.9 (linuxcnc-uspace) and, as root, the unprivileged user lcnc (see
src/precontour/linuxcnc/run.py). Writes the configurations with
``precontour.linuxcnc.config.write_linuxcnc_config``, runs ``precontour run`` (the library
call) on the programs, runs the G-code on LinuxCNC's interpreter, planner and motion
controller and the stream through halstreamer, and prints markdown tables:

1. G-code timing per program: programmed against executed block end times (BlockTiming);
2. what changes it (the levers tried on the paper path): rotary words held, longer blocks,
   G64 forms, the INI accelerations raised;
3. the stream: samples, underruns, largest difference to the commands;
4. kinematics: LinuxCNC's xyzac-trt-kins / xyzbc-trt-kins joints against the library's at
   every programmed point and servo period of a TCP program (tests/linuxcnc/test_linuxcnc_kinematics.py
   does the same on the programs' first lines).

``--long`` adds LinuxCNC's impeller (G-code timing, about 25 min) and boat (stream, 10 min;
kinematics of the whole impeller and B-C boat, about 35 min). ``--out DIR`` keeps the
per-block timing tables (CSV), the recordings (npz) and the programs.
"""

from __future__ import annotations

import argparse
import datetime
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests" / "linuxcnc"))

from precontour import load_machine  # noqa: E402
from precontour.tables import read_trajectory  # noqa: E402
from precontour.toolpath import read_program  # noqa: E402
from precontour.linuxcnc.config import write_linuxcnc_config  # noqa: E402
from precontour.linuxcnc.run import (block_timing, linuxcnc_unavailable,  # noqa: E402
                                              run_gcode, run_stream)
from precontour.trajectory.builtin_paths import builtin_path  # noqa: E402
from precontour.workflow import RunOutputs, run_program, write_run_outputs  # noqa: E402

from test_linuxcnc_kinematics import DEMOS, _head_with_dwells, _stationary_point  # noqa: E402


def run_outputs(source: Path, out: Path, machine: str, controller: str = "pid-high",
                tcp: bool = False):
    out.mkdir(parents=True, exist_ok=True)
    outputs = RunOutputs(program=out / "comp.ngc", stream=out / "comp.txt",
                         commands=out / "comp.csv")
    start = time.perf_counter()
    result = run_program(source, outputs, machine=machine, controller=controller, tcp=tcp)
    write_run_outputs(result, outputs, [source])
    print(f"  run {source.name} on {machine}: {time.perf_counter() - start:.0f} s",
          file=sys.stderr)
    return outputs, result


def timing_row(name: str, text: str, rec, out: Path | None, note: str = "",
               axis_names: str = "XYZAC") -> str:
    timing = block_timing(text, rec, axis_names=axis_names)
    programmed, executed = timing.duration
    late = timing.late[timing.measured]
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        stem = re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")
        np.savez_compressed(out / f"{stem}-record.npz", sample=rec.sample, **rec.columns)
        np.savetxt(out / f"{stem}-blocks.csv",
                   np.column_stack([timing.line, timing.programmed, timing.executed,
                                    timing.rotary]),
                   delimiter=",", header="line,programmed_s,executed_s,moves_rotary",
                   comments="", fmt=["%d", "%.6f", "%.6f", "%d"])
    worst = np.abs(late).max() * 1e3 if late.size else float("nan")
    return (f"| {name} | {timing.line.size} ({int(timing.rotary.sum())}) | {programmed:.3f} | "
            f"{executed:.3f} ({100 * (executed / programmed - 1):+.1f} %) | "
            f"{timing.late_blocks()} of {int(timing.measured.sum())} | {worst:.1f} | {note} |")


def steady_stretch(timing, source_line, first: int, last: int, margin: float = 0.05):
    """Lateness spread (ms) over the blocks of source lines first..last, leaving out those
    within ``margin`` s of the stretch's ends."""
    blocks = np.flatnonzero((source_line >= first) & (source_line <= last))
    t = timing.programmed[blocks]
    steady = blocks[(t > t[0] + margin) & (t < t[-1] - margin)]
    late = timing.late[steady]
    return steady.size, float(np.ptp(late[np.isfinite(late)]) * 1e3)


def variant(text: str, *, hold_rotary: bool = False, g64: str | None = None) -> str:
    lines = []
    for line in text.splitlines():
        if hold_rotary and line.startswith("G1 "):
            line = re.sub(r" [AC]-?[0-9.]+", "", line)
        if g64 is not None and line.startswith("G64"):
            line = g64
        lines.append(line)
    return "\n".join(lines) + "\n"


def long_blocks(commands: Path, every: int) -> str:
    """The commands as G93 blocks of ``every`` servo periods (no decimation tolerance)."""
    traj = read_trajectory(commands)
    kept = np.unique(np.r_[np.arange(0, traj.n_samples, every), traj.n_samples - 1])
    deg = np.column_stack([traj.q[:, :3], np.degrees(traj.q[:, 3:])])[kept]
    fmt = "X{:.5f} Y{:.5f} Z{:.5f} A{:.6f} C{:.6f}"
    # G64 without P: no blend tolerance, the fastest blends (G64 P0.001 made them slower)
    lines = ["%", "G21 G90 G94", "G0 " + fmt.format(*deg[0]), "G64", "G93"]
    for k in range(1, kept.size):
        dt = traj.t[kept[k]] - traj.t[kept[k - 1]]
        lines.append("G1 " + fmt.format(*deg[k]) + f" F{60.0 / dt:.10g}")
    return "\n".join(lines + ["G94", "M2", "%"]) + "\n"


def path_deviation(commands: Path, rec) -> float:
    """Largest distance (mm) from a commanded X Y Z sample to the executed path."""
    from scipy.spatial import cKDTree

    traj = read_trajectory(commands)
    world = np.column_stack([rec.columns[f"w{i}"] for i in range(3)])
    moving = np.flatnonzero(rec.columns["line"] > 0)
    dense = world[moving[0]:moving[-1] + 1]
    # the executed polyline sampled 10x finer, so that the distance is to the path
    fine = (dense[:-1, None, :] + np.linspace(0, 1, 10)[None, :, None]
            * np.diff(dense, axis=0)[:, None, :]).reshape(-1, 3)
    return float(cKDTree(fine).query(traj.q[:, :3])[0].max())


def scaled_accelerations(config: Path, factor: float, out: Path) -> Path:
    import shutil

    shutil.copytree(config, out)
    ini = out / "headless.ini"
    text = re.sub(r"^MAX_ACCELERATION = (.*)$",
                  lambda m: f"MAX_ACCELERATION = {float(m.group(1)) * factor:.12g}",
                  ini.read_text(), flags=re.M)
    ini.write_text(text)
    return out


def stream_row(name: str, stream: Path, commands: Path, config: Path) -> str:
    traj = read_trajectory(commands)
    expected = np.column_stack([traj.q[:, :3], np.degrees(traj.q[:, 3:])])
    start = time.perf_counter()
    rec = run_stream(config, stream, timeout=7200)
    wall = time.perf_counter() - start
    diff = np.abs(rec.joints - expected).max() if rec.joints.shape == expected.shape else np.inf
    return (f"| {name} | {expected.shape[0]} ({expected.shape[0] * traj.ts:.1f} s) | "
            f"{rec.joints.shape[0]} | {int(rec.columns['underruns'][-1])} | {rec.overruns} | "
            f"{diff:.1e} | {wall:.0f} s |")


def kinematics_row(machine_name: str, demo: str, lines: int, speedup: float,
                   config: Path, work: Path, out: Path | None = None) -> str:
    machine = load_machine(machine_name)
    program = _head_with_dwells(DEMOS / demo, lines, work / demo, speedup)
    rec = run_gcode(config, program, timeout=7200)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(out / f"kinematics-{demo}-record.npz", sample=rec.sample,
                            **rec.columns)
    joints = rec.joints
    world = np.column_stack([rec.columns[f"w{i}"] for i in range(5)])
    parsed = read_program(program, machine, tcp=True)
    last = np.r_[np.flatnonzero(np.diff(parsed.line)), parsed.line.size - 1]
    q = parsed.q[last]
    tip, _ = machine.kinematics.forward(q)
    targets = np.column_stack([tip, np.degrees(q[:, 3:])])
    expected = np.column_stack([q[:, :3], np.degrees(q[:, 3:])])
    at, found, want = 0, [], []
    for k, target in enumerate(targets):
        n = _stationary_point(world, at, target)
        if n is None:
            print(f"  {demo}: programmed point {k} (line {parsed.line[last[k]]}) not found "
                  "standing still", file=sys.stderr)
            continue
        found.append(joints[n + 4])
        want.append(expected[k])
        at = n
    points = np.abs(np.array(found) - np.array(want))
    inverse = np.column_stack([machine.kinematics.linear_axes(
        world[:, :3], np.radians(world[:, 3]), np.radians(world[:, 4])), world[:, 3:]])
    running = np.flatnonzero(rec.columns["line"] > 0)
    n = np.arange(max(running[0], 3), running[-1])
    every = np.abs(joints[n] - (inverse[n - 3] + 4 * inverse[n - 2] + inverse[n - 1]) / 6)
    rad = np.pi / 180
    return (f"| {machine_name} | {demo} ({'all' if lines > 10**5 else lines} motion lines) | "
            f"{len(found)} of {len(targets)} | {points[:, :3].max() * 1e3:.4f} um, "
            f"{points[:, 3:].max() * rad * 1e6:.4f} urad | {n.size} | "
            f"{every[:, :3].max() * 1e3:.4f} um, {every[:, 3:].max() * rad * 1e6:.4f} urad |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--long", action="store_true", help="also the impeller and the boat")
    parser.add_argument("--out", type=Path, help="keep per-block tables and programs here")
    args = parser.parse_args()
    why = linuxcnc_unavailable()
    if why:
        print(f"cannot measure: {why}", file=sys.stderr)
        return 2
    version = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "linuxcnc-uspace"],
                             capture_output=True, text=True).stdout.strip() or "unknown"
    work = Path(tempfile.mkdtemp(prefix="measure-linuxcnc-"))
    out = args.out
    configs = {}
    for name in ("zhang2013", "linuxcnc-xyzac-trt", "linuxcnc-xyzbc-trt"):
        configs[name] = work / f"cfg-{name}"
        write_linuxcnc_config(load_machine(name), configs[name])

    path = builtin_path("paper")
    paper_csv = work / "paper.csv"
    np.savetxt(paper_csv, np.column_stack([path.P, path.O]), delimiter=",",
               header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.9f")
    paper, _ = run_outputs(paper_csv, work / "paper", "zhang2013")
    threeplus2_src = ROOT / "tests" / "linuxcnc" / "data" / "3plus2.ngc"
    threeplus2, result32 = run_outputs(threeplus2_src, work / "3plus2", "zhang2013")

    print(f"Measured {datetime.date.today().isoformat()} with LinuxCNC {version} "
          "(linuxcnc-uspace, POSIX non-realtime, servo period 1 ms); precontour run, "
          "controller pid-high.\n")
    print("| program | blocks (moving a rotary axis) | programmed s | executed s | "
          "blocks off by > 1 servo period | worst block, ms | note |")
    print("|---|---|---|---|---|---|---|")
    z = configs["zhang2013"]
    text = paper.program.read_text()
    print(timing_row("paper, CL data, zhang2013", text, run_gcode(z, paper.program), out,
                     "run's G-code as written"), flush=True)
    text32 = threeplus2.program.read_text()
    rec32 = run_gcode(z, threeplus2.program)
    timing32 = block_timing(text32, rec32)
    source_line = result32.limited.line[result32.program.kept[1:]]
    n_steady, spread = steady_stretch(timing32, source_line, 10, 16)
    print(timing_row("3+2 with arcs (tests/linuxcnc/data/3plus2.ngc), zhang2013", text32, rec32,
                     out, f"steady contour, lines 10-16 ({n_steady} blocks, A C still): "
                          f"lateness spread {spread:.3f} ms"), flush=True)
    if args.long:
        imp = DEMOS / "impeller-7bl-xyzac.ngc"
        impeller, _ = run_outputs(imp, work / "impeller", "linuxcnc-xyzac-trt", tcp=True)
        print(timing_row("LinuxCNC impeller, --tcp, linuxcnc-xyzac-trt",
                         impeller.program.read_text(),
                         run_gcode(configs["linuxcnc-xyzac-trt"], impeller.program,
                                   timeout=7200), out), flush=True)

    print("\nLevers tried on the paper path (same commands):\n")
    print("| program | blocks (moving a rotary axis) | programmed s | executed s | "
          "blocks off by > 1 servo period | worst block, ms | note |")
    print("|---|---|---|---|---|---|---|")
    for label, g64, name in (("G64 (no P: no blend tolerance)", "G64", "g64"),
                             ("G64 P0.01 Q0", "G64 P0.01 Q0", "g64-p0.01-q0")):
        program = work / f"paper-{name}.ngc"
        program.write_text(variant(text, g64=g64))
        print(timing_row(f"paper, {label}", program.read_text(), run_gcode(z, program), out),
              flush=True)
    held = work / "paper-held.ngc"
    held.write_text(variant(text, hold_rotary=True))
    print(timing_row("paper, A C words left out (rotary axes held)", held.read_text(),
                     run_gcode(z, held), out, "not the part: shows the rotary cause"),
          flush=True)
    for every in (50, 100):
        program = work / f"paper-{every}ms.ngc"
        program.write_text(long_blocks(paper.commands, every))
        rec = run_gcode(z, program)
        print(timing_row(f"paper, blocks of {every} ms, G64", program.read_text(), rec, out,
                         f"path {path_deviation(paper.commands, rec):.2f} mm off the "
                         "commands"), flush=True)
    for factor in (10, 100):
        faster = scaled_accelerations(z, factor, work / f"cfg-acc{factor}")
        print(timing_row(f"paper, INI accelerations x{factor}", text,
                         run_gcode(faster, paper.program), out,
                         "limits no longer the machine's"), flush=True)

    print("\nThe stream (streamer + halstreamer, stream.hal of linuxcnc-config):\n")
    print("| program | commands | samples recorded | underruns | recorder overruns | "
          "largest difference (mm, deg; printed to 6 decimals) | wall time |")
    print("|---|---|---|---|---|---|---|")
    print(stream_row("paper, zhang2013", paper.stream, paper.commands, z), flush=True)
    if args.long:
        boat, _ = run_outputs(DEMOS / "boat-xyzac.ngc", work / "boat", "linuxcnc-xyzac-trt",
                              tcp=True)
        print(stream_row("LinuxCNC boat (A-C), --tcp, linuxcnc-xyzac-trt", boat.stream,
                         boat.commands, configs["linuxcnc-xyzac-trt"]), flush=True)

    print("\nKinematics: joints of LinuxCNC's module against the library's inverse "
          "kinematics (largest difference):\n")
    print("| machine | TCP program | programmed points compared | at programmed points | "
          "servo periods compared | every servo period |")
    print("|---|---|---|---|---|---|")
    cases = [("linuxcnc-xyzac-trt", "impeller-7bl-xyzac.ngc", 24, 4.0),
             ("linuxcnc-xyzbc-trt", "boat-xyzbc.ngc", 12, 4.0)]
    if args.long:
        cases = [("linuxcnc-xyzac-trt", "impeller-7bl-xyzac.ngc", 10**6, 1.0),
                 ("linuxcnc-xyzbc-trt", "boat-xyzbc.ngc", 10**6, 1.0)]
    for machine_name, demo, lines, speedup in cases:
        print(kinematics_row(machine_name, demo, lines, speedup, configs[machine_name], work,
                             out), flush=True)
    if out is not None:
        import shutil

        shutil.copytree(work, out / "work", dirs_exist_ok=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
