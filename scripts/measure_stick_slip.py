"""How much of `run`'s per-line comparison a picometre decides: write docs/stick-slip.md.

`run` judges the compensated program line by line against the uncompensated one on the
worst of five draws of the realistic virtual machine (docs/run.md). This script measures
what such a comparison tells apart, on LinuxCNC's trunnion-table examples
(``precontour run PROGRAM --tcp --machine linuxcnc-xyzac-trt --controller pid-high``):

- the uncompensated command run again, its encoder noise drawn afresh (what `run` already
  counts as each line's repeatability);
- the uncompensated command changed by a smooth wave of 1 pm or 1 nm (1 % of it in rad on A
  and C) wherever its axis moves faster than 1e-6 mm/s (1e-8 rad/s), and left as it is
  elsewhere, so that its velocity keeps its sign (the 1 nm wave's fade, 20 ms, does not on
  some samples: the table counts them);
- the same waves wherever the axis does not rest exactly, so that where the reference creeps
  slower than the wave the command's velocity changes sign;
- the compensated command `run` writes;

each judged against the uncompensated command on the same draws, by `run`'s rule (the block
margins and the line's repeatability), with the number of samples on which the command's
velocity has the other sign than the reference's where the reference is slow (below 1e-3
mm/s, 1e-5 rad/s; zero velocity counting as a sign of its own).

Run from the repository root (a few minutes per program):

    python scripts/measure_stick_slip.py [--programs boat-xyzac.ngc] [--demos DIR]
                                         [--output docs/stick-slip.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from docpage import DOCS, markdown_table, replace_section, stamp
from measure_programs import PROGRAMS, find_demo
from precontour.compensation.blocks import (RELATIVE_MARGIN, TIP_MARGIN, Judgement, judge,
                                           with_repeatability, worse_blocks)
from precontour.compensation.blend import taper_weight
from precontour.workflow import RunOutputs, errors_on_draws, run_program

MACHINE, CONTROLLER = "linuxcnc-xyzac-trt", "pid-high"
#: Period of the perturbing wave, s: slow against every servo dynamics, so that it changes
#: positions by its amplitude and velocities by 2 pi amplitude / period (below 1e-8 mm/s).
WAVE_PERIOD = 7.0
#: Below these speeds (mm/s on X Y Z, rad/s on A C) the sign-keeping wave is left out.
MOVING = np.array([1e-6] * 3 + [1e-8] * 2)
#: The reference is "slow" below these speeds (mm/s, rad/s) for the sign count.
SLOW = np.array([1e-3] * 3 + [1e-5] * 2)
#: The waves added to the uncompensated command: (amplitude in mm, keep the velocity's sign).
AMPLITUDES = ((1e-9, True), (1e-6, True), (1e-9, False), (1e-6, False))
#: Time (s) over which the wave fades in and out where it is left out (C2).
FADE = 0.02

INTRO = """# Stick-slip and the per-line comparison, measured

Why `run`'s compensated programs are worse than the uncompensated ones on some lines of
LinuxCNC's real programs ([programs, measured](programs.md)), and how much of that comparison a
picometre decides. Written by `scripts/measure_stick_slip.py`, one section per run, each
stamped; do not edit by hand. What `run` checks: [run](run.md); the virtual machine:
[method](method.md).

The controller of the virtual machine adds the nominal friction torque at the *commanded* speed
(paper Fig. 10; commanded speeds below 1e-8 rad/s count as zero): at a creeping speed, nearly
the full static friction, with the speed's sign. So where an axis creeps or rests, a command
whose velocity changes sign, by however little, switches the full static friction torque from
one side to the other: it decides where the axis breaks away, how far it slips once friction
drops to its Coulomb level, and what the integrator holds after, and that decides the axis's
sticking and slipping long after. The tables below measure this with waves added to the
uncompensated command: a picometre wave that keeps every velocity's sign changes few lines; the
same wave where the reference creeps changes many; and the lines where the compensated
command is worse than the uncompensated one are nearly all lines where it moves against the
direction of a creeping or resting reference (its lead before a start, its ripple at a rest)."""


def perturbed(t: np.ndarray, q: np.ndarray, amplitude: float, keep_sign: bool,
              seed: int = 1) -> np.ndarray:
    """``q`` plus a wave of ``amplitude`` mm (1 % of it in rad on A and C), left out where the
    axis rests exactly, or with ``keep_sign`` wherever it moves slower than :data:`MOVING`."""
    ts = t[1] - t[0]
    rng = np.random.default_rng(seed)
    out = np.array(q, dtype=float, copy=True)
    for axis in range(5):
        if keep_sign:
            outside = np.abs(np.gradient(q[:, axis], ts)) < MOVING[axis]
        else:
            still = np.diff(q[:, axis]) == 0
            outside = np.zeros(q.shape[0], dtype=bool)
            outside[1:-1] = still[1:] & still[:-1]
            outside[0], outside[-1] = still[0], still[-1]
        scale = amplitude if axis < 3 else 0.01 * amplitude
        wave = np.sin(2 * np.pi * t / WAVE_PERIOD + rng.uniform(0, 2 * np.pi))
        fade_out = taper_weight(outside, ts, hold=0.0, width=FADE)[0]
        out[:, axis] += scale * wave * (1.0 - fade_out)
    return out


def length(mm: float) -> str:
    """A length in picometres or nanometres."""
    return f"{1e9 * mm:g} pm" if mm < 1e-6 else f"{1e6 * mm:g} nm"


def opposed_steps(q_reference: np.ndarray, q: np.ndarray, ts: float) -> np.ndarray:
    """Per step and axis (shape (N - 1, 5)): the reference moves slower than :data:`SLOW` and
    the command's step has another sign than the reference's (0 a sign of its own)."""
    step_reference = np.diff(q_reference, axis=0)
    step = np.diff(q, axis=0)
    slow = np.abs(step_reference) < SLOW * ts
    return slow & (np.sign(step) != np.sign(step_reference))


def one_draw(judgement: Judgement, draw: int) -> Judgement:
    """``judgement`` on its draw ``draw`` alone (its repeatability kept)."""
    pick = slice(draw, draw + 1)
    return replace(judgement, summaries=judgement.summaries[pick],
                   tip_max=judgement.tip_max[pick], tip_mean=judgement.tip_mean[pick],
                   orientation_max=judgement.orientation_max[pick],
                   orientation_mean=judgement.orientation_mean[pick])


def program_section(path: Path, folder: Path) -> str:
    result = run_program(path, RunOutputs(program=folder / f"{path.stem}-comp.ngc"),
                         machine=MACHINE, controller=CONTROLLER, tcp=True)
    reference = result.limited.reference
    machine = result.machine
    check = result.draws
    ensemble = check.ensemble
    before, after = check.before, check.after
    t, ts = reference.t, reference.ts

    def judged(q):
        return judge(errors_on_draws(reference, q, machine, CONTROLLER, ensemble), check.starts)

    def row(label, judgement, q):
        worst = judgement.worst["tip_max_um"]
        nominal = judgement.summaries[0]["tip_max_um"]
        return [label, f"{worst:.1f}", f"{nominal:.1f}",
                f"{worse_blocks(judgement, before).sum():,}",
                f"{worse_blocks(judgement, before.without_repeatability()).sum():,}",
                "" if q is None else f"{int(opposed_steps(reference.q, q, ts).sum()):,}"]

    rows = [row("uncompensated", before, reference.q),
            row("uncompensated, run again (encoder noise drawn afresh)", check.again, None)]
    creeping = None
    for amplitude, keep_sign in AMPLITUDES:
        q = perturbed(t, reference.q, amplitude, keep_sign)
        judgement = judged(q)
        where = ("where the axis moves faster than 1e-6 mm/s" if keep_sign
                 else "wherever the axis does not rest exactly")
        rows.append(row(f"uncompensated + {length(amplitude)}, {where}", judgement, q))
        if not keep_sign and creeping is None:
            creeping = judgement
    rows.append(row("compensated (`run`)", after, result.commands.q))
    # the compensated command against the uncompensated one's scatter under the 1 pm wave too
    scatter = with_repeatability(before.without_repeatability(), creeping)
    wider = replace(before, tip_repeatability=np.maximum(before.tip_repeatability,
                                                         scatter.tip_repeatability),
                    orientation_repeatability=np.maximum(before.orientation_repeatability,
                                                         scatter.orientation_repeatability))
    worse_lines = np.flatnonzero(worse_blocks(after, before))
    # draw by draw: each draw's line against the same draw's uncompensated line, by run's rule
    draws_worse = sum(worse_blocks(one_draw(after, d), one_draw(before, d)).astype(int)
                      for d in range(ensemble.draws))
    draws_better = (after.tip_max < before.tip_max
                    - np.maximum(TIP_MARGIN, RELATIVE_MARGIN * before.tip_max)).sum(axis=0)
    opposed = np.concatenate([opposed_steps(reference.q, result.commands.q, ts).any(axis=1),
                              [False]])
    has_opposed = np.logical_or.reduceat(opposed, check.starts)
    share_worse = has_opposed[worse_lines].mean() if worse_lines.size else float("nan")
    table = markdown_table(
        ["command", "worst draw: tip max, um", "machine file's machine: tip max, um",
         "lines worse (margins and repeatability)", "lines worse (margins alone)",
         "samples against the slow reference's direction"],
        rows, align="lrrrrr")
    return "\n".join([
        f"## `{path.name}` ({check.starts.size:,} lines, {reference.n_samples:,} samples)",
        "",
        stamp(),
        "",
        f"`precontour run {path.name} --tcp --machine {MACHINE} --controller {CONTROLLER}`, "
        f"its {ensemble.draws} draws (the machine file's machine and {ensemble.draws - 1} draws "
        "of it: friction +-2 %, J and B +-1 %, a noisy 10 nm encoder). Each command is "
        "judged against the uncompensated one on the same draws, line by line, worst draw "
        "against worst draw, beyond 0.1 um / 1 urad or 5 % and the line's repeatability (the "
        "largest change of its max when the uncompensated command is run again).",
        "",
        table,
        "",
        f"- The compensated command is worse on {worse_lines.size:,} lines. Against the "
        "uncompensated command's scatter under the 1 pm wave where the axis creeps as well "
        f"(its repeatability widened by it), on {worse_blocks(after, wider).sum():,}.",
        f"- Draw by draw (each draw's line against the same draw's uncompensated line, beyond "
        f"the same margins and repeatability), the compensated command is worse on every draw "
        f"on {int((draws_worse == ensemble.draws).sum()):,} lines and on most draws on "
        f"{int((2 * draws_worse > ensemble.draws).sum()):,}; its max tip error is lower "
        f"beyond the margins on every draw on {int((draws_better == ensemble.draws).sum()):,}.",
        f"- {100 * share_worse:.0f} % of those lines hold a sample where the compensated "
        "command moves against the slow reference's direction (or moves while it rests), "
        f"against {100 * has_opposed.mean():.0f} % of all lines.",
        "",
    ])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--programs", default=",".join(PROGRAMS),
                        help=f"LinuxCNC examples to run (default {','.join(PROGRAMS)})")
    parser.add_argument("--demos", type=Path, default=None,
                        help="folder holding LinuxCNC's example programs")
    parser.add_argument("--output", type=Path, default=DOCS / "stick-slip.md",
                        help="page whose sections are rewritten (default docs/stick-slip.md)")
    args = parser.parse_args(argv)
    replace_section(args.output, "intro", INTRO)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.programs.split(","):
            path = find_demo(name, args.demos)
            if path is None:
                parser.error(f"{name} not found (give --demos DIR)")
            body = program_section(path, Path(tmp))
            print(f"wrote {replace_section(args.output, Path(name).stem, body)} "
                  f"(section {Path(name).stem})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
