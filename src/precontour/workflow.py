"""Program in, program out: the ``precontour run`` and ``precontour export`` workflows.

``run``: read an NC program (or CL data), plan its trajectory, predict and contour
pre-compensate the axis commands, keep them within the machine's limits (slowing down locally
and compensating again where needed), optionally learn against the realistic virtual
machine within those limits (``learn``), check uncompensated and compensated commands on the
realistic virtual machine (discrete controller, friction, feed-forward friction compensation),
and write the compensated program (G-code), optionally a halstreamer file and the command
table. ``export``: write an existing command file in one of those formats. Every output
location is checked before any computing, and nothing is written when a step fails.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from itertools import islice
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .compensation.blocks import Judgement
from .compensation.pieces import AT_ONCE_SAMPLES, contour_errors_program
from .compensation.segments import learn_by_segments
from .compensation.programmed_end import required_final_rest, with_final_rest
from .compensation.within_limits import (LimitedCompensation, compensate_within_limits,
                                         learn_within_limits, planned_if_uncompensated)
from .defaults import (DEFAULT_CHECK_DRAWS, DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                       DEFAULT_CORNER_TOLERANCE, DEFAULT_DWELL,
                       DEFAULT_FEED, EXPORT_FORMATS, default_max_samples)
from .errors import (InputError, MachineLimitError, ToleranceError, is_whole_number, notice,
                     warning)
from .files import OutputSet, check_signals
from .machine.machine_file import Machine, load_machine
from .parallel import map_ordered
from .options import (LearningOptions, LimitOptions, ToleranceOptions, learning_options,
                      limit_options, with_former_spellings)
from .planning.tolerance import ContourTolerance, FeedWithinTolerance, feed_within_tolerance
from .prediction.contour import ContourErrors
from .simulation.ensemble import MachineEnsemble, ensemble_actual
from .simulation.virtual_machine import realistic_actual
from .tables import (SUPPORTED_SUFFIXES, check_output_path, read_trajectory,
                     trajectory_columns, write_columns, write_text)
from .toolpath import (EXTENSIONS, PROGRAM_FORMATS, read_program, read_toolpath_report,
                       toolpath_format)
from .toolpath.writers import (GcodeProgram, ProgramInfo, gcode_tolerances, gcode_program,
                               halstreamer_lines, machine_axes_passthrough)
from .trajectory.generate import generate_trajectory, unfed_notice
from .trajectory.program import check_program_samples, program_trajectory
from .trajectory.limits import AxisLimits, check_limits, check_travel
from .trajectory.sampled import Trajectory

#: Extensions a G-code output may have (those the readers take as G-code).
GCODE_SUFFIXES: tuple[str, ...] = EXTENSIONS["gcode"]

#: Samples from which the two virtual-machine runs go to two processes when ``workers`` is
#: None. The compiled virtual machine already runs the five axes on two threads, so on this
#: 2-core machine two processes did not pay: on LinuxCNC's impeller (1.5 * 10^6 samples after
#: slowing) the two runs took 12.0 s in two processes and 9.9 s in one. Only far longer
#: programs, on machines with more cores, may gain.
PARALLEL_MIN_SAMPLES = 20_000_000

Progress = Callable[[int, int, str], None]


def load_program_trajectory(path: str | Path, machine: Machine, *, tcp: bool = False,
                            dwell: float = DEFAULT_DWELL,
                            corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                            corner_orientation_tolerance: float | None =
                            DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                            max_samples: int | None = None, format: str | None = None,
                            tool_table=None
                            ) -> tuple[Trajectory, Sequence[tuple[int, str]] | None]:
    """The planned trajectory of a program, and its non-motion lines to keep (or None).

    The one place ``run`` reads its input (:func:`read_run_program`, then
    :func:`plan_run_program`). G-code is read as a CNC executes it
    (:func:`~precontour.toolpath.read_program`, then
    :func:`~precontour.trajectory.program_trajectory` at the machine's servo period): the
    trajectory carries the source line of every sample, and the program's pass-through lines
    (tool change, spindle, coolant, comments) come back for the output program. ``tcp`` puts
    the whole program in tool centre point mode. CL data (CSV, APT) gives the tool tip
    already: it goes through :func:`~precontour.trajectory.generate.generate_trajectory`, its
    samples carry the file line of the CL point they move to, and it has no lines to keep.
    ``dwell``, ``corner_tolerance``, ``corner_orientation_tolerance`` (G-code only) and
    ``max_samples`` (default
    :func:`~precontour.defaults.default_max_samples`) are the planning options of the
    ``trajectory`` command. ``format``: the file's format, instead of the one its extension
    says (:func:`~precontour.toolpath.read_toolpath`'s); ``tool_table``: tool lengths for
    G-code (a LinuxCNC ``.tbl`` file or a mapping; None: the machine file's ``[tools]``).
    """
    source = read_run_program(path, machine, tcp=tcp, dwell=dwell, max_samples=max_samples,
                              format=format, tool_table=tool_table)
    return plan_run_program(source, machine, dwell=dwell, corner_tolerance=corner_tolerance,
                            corner_orientation_tolerance=corner_orientation_tolerance,
                            max_samples=max_samples)


@dataclass(frozen=True)
class RunProgram:
    """A program as ``run`` read it: a G-code ``program`` (``tcp``: read with ``--tcp``) or
    CL data (``toolpath``, the :func:`~precontour.toolpath.read_toolpath_report`)."""

    path: Path
    program: object | None = None
    toolpath: object | None = None
    tcp: bool = False

    @property
    def format(self) -> str:
        """``"gcode"`` for an NC program (G-code or Heidenhain), or the CL data's format
        (``"clcsv"``, ``"apt"``)."""
        return "gcode" if self.program is not None else self.toolpath.format


def read_run_program(path: str | Path, machine: Machine, *, tcp: bool = False,
                     dwell: float = DEFAULT_DWELL, max_samples: int | None = None,
                     format: str | None = None, tool_table=None) -> RunProgram:
    """Read and check ``run``'s input, before any progress is shown: every error in the file
    comes first, and for G-code also a trajectory too long to make (the sample estimate of
    :func:`~precontour.trajectory.program.check_program_samples`, as ``trajectory``).
    ``format``, ``tool_table``: as :func:`~precontour.toolpath.read_toolpath`'s (None: from
    the extension; the machine file's ``[tools]``)."""
    format = toolpath_format(path, format)
    if format in PROGRAM_FORMATS:
        program = read_program(path, machine, tcp=tcp, format=format,
                               tool_table=tool_table)
        for text in program.notices:
            notice(text)
        check_program_samples(program, machine, ts=machine.servo_period, dwell=dwell,
                              max_samples=max_samples)
        return RunProgram(Path(path), program=program, tcp=tcp)
    if tcp:
        raise InputError("--tcp applies to G-code programs only (CL data gives the tool tip "
                         "already)", source=str(path), field="--tcp")
    if tool_table is not None:
        raise InputError("--tool-table applies to G-code programs only (CL data gives the tool "
                         "tip already)", source=str(path), field="--tool-table")
    report = read_toolpath_report(path, machine=machine, format=format)
    said = unfed_notice(report.toolpath)
    if said is not None:
        notice(said)
    return RunProgram(Path(path), toolpath=report)


def plan_run_program(source: RunProgram, machine: Machine, *, dwell: float = DEFAULT_DWELL,
                     corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                     corner_orientation_tolerance: float | None =
                     DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                     max_samples: int | None = None, feed_scale: float = 1.0
                     ) -> tuple[Trajectory, Sequence[tuple[int, str]] | None]:
    """The planned trajectory of a program read by :func:`read_run_program`, and its
    non-motion lines to keep (None for CL data). ``feed_scale``: the programmed feeds times
    this (a feed override: G-code feed moves take their programmed time over it, rapids
    keep the rapid rate; CL data's feeds and the default feed are multiplied); the axis
    limits hold whatever it is."""
    max_samples = default_max_samples() if max_samples is None else int(max_samples)
    if not (np.isfinite(feed_scale) and feed_scale > 0):
        raise InputError(f"the feed scale must be positive and finite, got {feed_scale!r}",
                         field="--feed-scale-max")
    if source.program is not None:
        program = source.program
        if feed_scale != 1.0:
            program = replace(program, duration=program.duration / feed_scale,
                              feed=program.feed * feed_scale)
        # the output gives machine axes: lines that switch TCP mode on or off stay comments
        passthrough = machine_axes_passthrough(program.passthrough, tcp=program.tcp,
                                               tcp_all=source.tcp)
        return program_trajectory(program, machine, ts=machine.servo_period, dwell=dwell,
                                  tolerance=corner_tolerance,
                                  orientation_tolerance=corner_orientation_tolerance,
                                  max_samples=max_samples), passthrough
    report = source.toolpath
    toolpath = report.toolpath
    if feed_scale != 1.0 and toolpath.feed is not None:
        toolpath = replace(toolpath, feed=np.asarray(toolpath.feed, dtype=float) * feed_scale)
    return generate_trajectory(toolpath, machine, ts=machine.servo_period, dwell=dwell,
                               feed=DEFAULT_FEED * feed_scale, max_samples=max_samples,
                               lines=report.lines), None


@dataclass(frozen=True)
class RunOutputs:
    """Where ``run`` writes: the G-code program, and optionally a halstreamer file, the
    command table and a report folder with the files ``report_files`` (the report's own
    names, checked against the inputs and the other outputs before computing)."""

    program: Path
    stream: Path | None = None
    commands: Path | None = None
    report: Path | None = None
    report_files: tuple[str, ...] = ()

    def files(self) -> list[Path]:
        return [p for p in (self.program, self.stream, self.commands) if p is not None]

    def output_set(self, inputs: Sequence[str | Path]) -> OutputSet:
        """The outputs as one :class:`~precontour.files.OutputSet`, each checked now: written
        inside ``with`` it, they replace the old files together or not at all."""
        return check_run_outputs(self, inputs)


@dataclass(frozen=True)
class LargestError:
    """Where a simulated contour error of ``run`` is largest: the sample's time and the
    source line executing there.

    ``quantity``: ``"tip"`` (``value`` in mm) or ``"orientation"`` (rad); ``commands``:
    ``"compensated"`` or ``"uncompensated"``; ``line``: the G-code line, or the file line of
    the CL row the tool is moving to (None when the trajectory carries no lines); ``where``:
    how the source names it, ``"line"`` (G-code) or ``"row"`` (CL data, as its readers'
    messages do). An error that is zero throughout (no rotary motion) is at no line."""

    quantity: str
    commands: str
    value: float
    time: float
    index: int
    line: int | None
    where: str = "line"

    @property
    def unit(self) -> str:
        return "um" if self.quantity == "tip" else "mrad"

    def format(self) -> str:
        """``tip, compensated  0.412 um  line 57  t = 12.345 s``, in columns."""
        at = f"{self.where} {self.line}" if self.line is not None and self.value > 0 else "-"
        digits = 3 if self.quantity == "tip" else 4
        return (f"{self.quantity + ', ' + self.commands:<28}{1e3 * self.value:10.{digits}f} "
                f"{self.unit:<5}{at:>12}   t = {self.time:.3f} s")


def largest_error(errors: np.ndarray, t: np.ndarray, line: np.ndarray | None, *,
                  quantity: str, commands: str, where: str = "line") -> LargestError:
    """The :class:`LargestError` of one error signal (the first sample of its maximum)."""
    k = int(np.argmax(errors))
    return LargestError(quantity=quantity, commands=commands, value=float(errors[k]),
                        time=float(t[k]), index=k,
                        line=None if line is None else int(line[k]), where=where)


@dataclass(frozen=True)
class WorseLine:
    """A source line where the compensated commands did worse than the uncompensated ones
    (:meth:`RunResult.worse_lines`): its first sample's time (s) and the max tip (mm) and
    orientation (rad) errors there, compensated then uncompensated."""

    line: int | None
    t: float
    tip: tuple[float, float]
    orientation: tuple[float, float]

    def format(self, where: str = "line") -> str:
        at = f"{where} {self.line}, " if self.line is not None else ""
        return (f"{at}t = {self.t:.3f} s: tip {1e3 * self.tip[0]:.3g} um against "
                f"{1e3 * self.tip[1]:.3g} um, orientation {1e6 * self.orientation[0]:.3g} urad "
                f"against {1e6 * self.orientation[1]:.3g} urad")


@dataclass(frozen=True)
class RunResult:
    """Everything ``run`` computed.

    ``planned`` is the trajectory as planned from the program; ``limited.reference`` the same
    after any local slow-down, and ``limited.result.trajectory`` the compensated commands on
    it. Contour errors before (uncompensated) and after are on the same timing.
    """

    source: str
    machine: Machine
    controller: str
    planned: Trajectory
    passthrough: Sequence[tuple[int, str]] | None
    limited: LimitedCompensation
    simulated_before: ContourErrors
    simulated_after: ContourErrors
    program: GcodeProgram
    tolerance: np.ndarray
    timings: dict = field(default_factory=dict)
    stream: Path | None = None
    #: With a contour-error tolerance (``run --tolerance``): both searches; ``planned`` is
    #: then the upper-bound plan and ``limited`` the compensated search's final compensation,
    #: its slow-downs and time map against that plan.
    feed: FeedWithinTolerance | None = None
    #: Both commands judged on the draws of a machine ensemble (``run --draws``), or None.
    draws: "DrawCheck | None" = None
    #: The source's format (``"gcode"``, ``"clcsv"``, ``"apt"``); None: from its extension.
    source_format: str | None = None
    #: Seconds of final rest added to the plan (in ``planned``) so that the corrections taper
    #: to zero and the program ends at its programmed end point
    #: (:func:`~.compensation.programmed_end.with_final_rest`); 0 where its dwell sufficed.
    final_rest_added: float = 0.0

    @property
    def place(self) -> str:
        """What a place in the source is called: a G-code program's line, CL data's row."""
        return ("line" if toolpath_format(self.source, self.source_format) in PROGRAM_FORMATS
                else "row")

    @property
    def commands(self) -> Trajectory:
        return self.limited.result.trajectory

    @property
    def predicted_before(self) -> ContourErrors:
        return self.limited.result.before

    @property
    def predicted_after(self) -> ContourErrors:
        return self.limited.result.after

    def largest_errors(self) -> tuple[LargestError, ...]:
        """Where the simulated tip and orientation errors are largest: with the compensated
        commands (what remains), then with the uncompensated ones. Samples are those of
        ``limited.reference`` (the timing after any slow-down), lines ``limited.line``."""
        t, line = self.limited.reference.t, self.limited.line
        return tuple(largest_error(getattr(errors, quantity), t, line, quantity=quantity,
                                   commands=commands, where=self.place)
                     for commands, errors in (("compensated", self.simulated_after),
                                              ("uncompensated", self.simulated_before))
                     for quantity in ("tip", "orientation"))

    def worse_lines(self) -> tuple[WorseLine, ...]:
        """The source lines (rows of CL data) where the compensated commands' simulated max
        tip or orientation error exceeds the uncompensated commands' there by more than the
        block margins (:mod:`.compensation.blocks`: 0.1 um / 1 urad, or 5 %), on the realistic
        virtual machine, largest excess first. Learning (``--learn``) makes its command
        nowhere worse on its ensemble; without it, this says where compensation hurts."""
        from .compensation.blocks import (ORIENTATION_MARGIN, TIP_MARGIN, block_starts, judge,
                                          worse_blocks)

        reference = self.limited.reference
        starts = block_starts(reference.n_samples, reference.ts, self.limited.line)
        before = judge([self.simulated_before], starts)
        after = judge([self.simulated_after], starts)
        bad = np.flatnonzero(worse_blocks(after, before))
        excess = np.maximum((after.tip_max[0] - before.tip_max[0]) / TIP_MARGIN,
                            (after.orientation_max[0] - before.orientation_max[0])
                            / ORIENTATION_MARGIN)
        line = self.limited.line
        return tuple(
            WorseLine(line=None if line is None else int(line[starts[b]]),
                      t=float(reference.t[starts[b]]),
                      tip=(float(after.tip_max[0, b]), float(before.tip_max[0, b])),
                      orientation=(float(after.orientation_max[0, b]),
                                   float(before.orientation_max[0, b])))
            for b in bad[np.argsort(-excess[bad], kind="stable")])

    def table(self) -> str:
        """The end-of-run table: contour errors before and after, duration, blocks."""
        rows = [("predicted", "before", self.predicted_before),
                ("predicted", "after", self.predicted_after),
                ("simulated", "before", self.simulated_before),
                ("simulated", "after", self.simulated_after)]
        lines = [f"{'contour errors':<22}{'tip max':>10}{'tip mean':>10}{'ori max':>10}"
                 f"{'ori mean':>10}",
                 f"{'':<22}{'um':>10}{'um':>10}{'mrad':>10}{'mrad':>10}"]
        where = self.place
        # the draws first: where an axis stops under friction one exact machine's answer is
        # decided by nanometres, so the median and the worst draw are the result (issue 42)
        if self.draws is not None:
            lines += self.draws.table(where, learned=self.limited.result.learning is not None)
            lines.append("on the machine file's machine alone (draw 0), predicted and "
                         "simulated:")
        for kind, when, errors in rows:
            s = errors.summary()
            lines.append(f"{kind + ' ' + when:<22}{s['tip_max_um']:10.3f}{s['tip_mean_um']:10.3f}"
                         f"{s['ori_max_mrad']:10.4f}{s['ori_mean_mrad']:10.4f}")
        for label, before, after in (("tip", self.simulated_before.tip,
                                      self.simulated_after.tip),
                                     ("orientation", self.simulated_before.orientation,
                                      self.simulated_after.orientation)):
            lines.append(f"simulated {label} reduction: max {_reduction(before.max(), after.max())}, "
                         f"mean {_reduction(before.mean(), after.mean())}")
        from .compensation.blocks import MARGINS

        lines.append("largest simulated errors, where:")
        lines += ["  " + largest.format() for largest in self.largest_errors()]
        worse = self.worse_lines()
        if worse:
            lines.append(f"compensated worse than uncompensated on {len(worse)} {where}(s) "
                         f"(beyond {MARGINS}), simulated, largest first:")
            lines += ["  " + w.format(where) for w in worse[:5]]
            if len(worse) > 5:
                lines.append(f"  ... and {len(worse) - 5} more")
        else:
            lines.append(f"no {where} worse than uncompensated (beyond {MARGINS}), simulated")
        duration = self.commands.duration
        planned = self.planned.duration - self.final_rest_added
        slow = self.limited.slowdowns
        learning = self.limited.result.learning
        if learning is not None:
            lines.append(f"learned against the virtual machine within the limits "
                         f"({learning.draws} draw(s), {learning.machine_runs} runs): kept "
                         f"{learning.chosen}")
            fallback = learning.fallback
            if fallback is not None and fallback.blocks:
                lines.append(f"  where the learned command would be worse than uncompensated "
                             f"on a draw, it fell back in {len(fallback.blocks)} block(s):")
                lines.extend("    " + b.format() for b in fallback.blocks[:10])
                if len(fallback.blocks) > 10:
                    lines.append(f"    ... and {len(fallback.blocks) - 10} more blocks")
        lines.append(f"duration {duration:.3f} s (planned {planned:.3f} s"
                     + (f"; +{self.final_rest_added:.3f} s of final rest, for the corrections "
                        "to taper to zero at the programmed end point"
                        if self.final_rest_added > 0 else "")
                     + (f"; slowed in {len(slow)} window(s), +{self.limited.added_time:.3f} s"
                        if slow else "; not slowed") + ")")
        for s in slow[:10]:
            lines.append("  slowed " + s.format())
        if len(slow) > 10:
            lines.append(f"  ... and {len(slow) - 10} more windows")
        left_out = self.limited.uncompensated
        if left_out:
            lines.append(f"compensation left out in {len(left_out)} window(s) where slowing down "
                         f"to {100 * self.limited.min_speed:g} % of the planned speed or "
                         "more could not keep the limits (the planned commands there): "
                         + ", ".join(f"t = {a:.3f}-{b:.3f} s" for a, b in left_out[:10])
                         + (" ..." if len(left_out) > 10 else ""))
        kinks = self.limited.kinks
        if kinks:
            lines.append(f"kinks of the corrections smoothed in {len(kinks)} window(s) (corners at "
                         "stops: the commands there blend into tracking-error "
                         "pre-compensation): " + ", ".join(f"t = {a:.3f}-{b:.3f} s"
                                                          for a, b in kinks[:5])
                         + (" ..." if len(kinks) > 5 else ""))
        smoothed = self.limited.smoothed
        if smoothed:
            lines.append(f"corrections smoothed instead of slowed down in {len(smoothed)} "
                         "window(s) (they broke a limit; blended into tracking-error "
                         "pre-compensation, predicted no worse there): "
                         + ", ".join(f"t = {a:.3f}-{b:.3f} s" for a, b in smoothed[:5])
                         + (" ..." if len(smoothed) > 5 else ""))
        lines.append(f"blocks written {self.program.n_blocks} (tolerance "
                     f"{self.tolerance[0]:g} mm, {self.tolerance[3]:g} rad; "
                     f"{self.commands.n_samples} samples at {self.commands.ts * 1e3:g} ms)")
        lines.append(self.linuxcnc_line())
        if self.feed is not None:
            lines.append(self.feed.table())
        return "\n".join(lines)

    def linuxcnc_line(self) -> str:
        """Which output to run on LinuxCNC, in one line (measured: docs/linuxcnc.md)."""
        stream = str(self.stream) if self.stream is not None else "write it with --stream FILE"
        rotary = " or ".join(self.machine.axis_names[3:])
        moving, blocks = self.program.rotary_blocks, self.program.n_blocks
        if moving:
            return (f"for LinuxCNC: run the stream ({stream}); LinuxCNC 2.9's planner "
                    f"stretches the {moving} of {blocks} G-code blocks that move {rotary} "
                    "(docs/linuxcnc.md)")
        return (f"for LinuxCNC: no G-code block moves {rotary}, and its planner keeps their "
                f"timing at a steady feed; the stream ({stream}) keeps it everywhere "
                "(docs/linuxcnc.md)")


def _reduction(before: float, after: float) -> str:
    return f"{100 * (1 - after / before):.1f} %" if before > 0 else "-"


def check_run_outputs(outputs: RunOutputs, inputs: Sequence[str | Path]) -> OutputSet:
    """Refuse, before computing, outputs that cannot be written or would overwrite an input
    or each other (the report's files included); return them as an
    :class:`~precontour.files.OutputSet`."""
    out = OutputSet(inputs)
    out.file(outputs.program, suffixes=GCODE_SUFFIXES)
    if outputs.stream is not None:
        out.file(outputs.stream)
    if outputs.commands is not None:
        out.file(outputs.commands, suffixes=SUPPORTED_SUFFIXES)
    if outputs.report is not None:
        out.folder(outputs.report, outputs.report_files, what="report", parent_must_exist=True)
    return out


def run_program(program: str | Path, outputs: RunOutputs | None = None, *, machine: str | Path,
                controller: str, tcp: bool = False, dwell: float = DEFAULT_DWELL,
                corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                corner_orientation_tolerance: float | None =
                DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                max_samples: int | None = None, iterations: int = 1,
                tolerance: np.ndarray | None = None, progress: Progress | None = None,
                workers: int | None = 1, learn: int | LearningOptions = 0,
                ensemble: MachineEnsemble | None = None,
                limits: LimitOptions = LimitOptions(),
                contour_tolerance: ToleranceOptions | ContourTolerance | None = None,
                min_speed: float | None = None, feed_scale_max: float | None = None,
                feed_scale_min: float | None = None,
                write_anyway: bool | None = None,
                draws: int = DEFAULT_CHECK_DRAWS, format: str | None = None,
                tool_table=None) -> RunResult:
    """Compute ``run`` (see the module docstring) without writing; :func:`write_run_outputs`
    writes. ``outputs``, where given, are checked before anything is computed (None: a library
    caller that keeps the result in memory). ``machine`` (a built-in name or a machine file)
    and ``controller`` have no default: a program compensated for another machine than the
    user's is wrong silently. ``tcp``, ``dwell``, ``corner_tolerance``,
    ``corner_orientation_tolerance``, ``max_samples``:
    planning, as :func:`load_program_trajectory`; ``format``: the program's format, instead
    of the one its extension says (as :func:`~precontour.toolpath.read_toolpath`'s);
    ``tool_table``: G-code tool lengths (as :func:`load_program_trajectory`'s).
    ``tolerance``: the G-code decimation
    tolerance per axis (:func:`~.toolpath.writers.gcode_tolerances`).

    ``learn``: passes of learning (a number, or :class:`~.options.LearningOptions`) against
    the realistic virtual machine after the compensation within limits
    (:func:`~.compensation.within_limits.learn_within_limits`; 0: none; skipped, with a
    notice, for a program not sampled at the servo period; segment by segment above
    :data:`~.compensation.pieces.AT_ONCE_SAMPLES` samples), every decision taken on the
    draws of the ensemble (the options', else ``ensemble``, default
    :class:`~.simulation.ensemble.MachineEnsemble` ()) and the result nowhere worse than
    uncompensated on them, block by block (each source line; :func:`learn_on_ensemble`).
    ``limits``: :class:`~.options.LimitOptions`, whose ``min_speed`` is the floor of the
    local slow-downs that keep the limits, a fraction of the planned speed (below it the
    planned commands are kept); ``run`` always keeps them.
    ``contour_tolerance``: :class:`~.options.ToleranceOptions` (or its ``tolerance``
    alone): find the fastest motion whose compensated contour errors keep it on the
    realistic virtual machine (each search's result checked on the draws of ``ensemble``,
    default :class:`~.simulation.ensemble.MachineEnsemble` ()), between its
    ``feed_scale_min`` and ``feed_scale_max`` times the programmed feed, and the
    uncompensated baseline the same way (:func:`~.planning.tolerance.feed_within_tolerance`;
    ``RunResult.feed``); where the compensated one is not met even at the lowest feed, raise
    :class:`~precontour.errors.ToleranceError` naming the place unless ``write_anyway``.
    ``min_speed``, ``feed_scale_max``, ``feed_scale_min``, ``write_anyway``: the former
    spellings of those options' fields, kept (with an options object, give them there).
    ``draws``: the machines both commands are checked on, the machine file's and
    ``draws - 1`` draws of the ensemble (:func:`check_on_draws`; ``RunResult.draws``, None
    for 1).
    ``workers``: processes for the two virtual-machine runs (1 by default; None: 2
    when the computer has two cores or more and the trajectory :data:`PARALLEL_MIN_SAMPLES`
    samples; more than 1 needs the calling script's own code under
    ``if __name__ == "__main__":``, as for any use of :mod:`multiprocessing`).
    Raises :class:`~precontour.errors.PrecontourError` subclasses on bad input and when the
    machine's limits cannot be kept."""
    if not is_whole_number(draws) or draws < 1:
        raise InputError(f"must be a whole number >= 1, got {draws!r}", field="--draws")
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
                        max_samples=max_samples, iterations=iterations, tolerance=tolerance,
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
    machine_obj = load_machine(machine)
    models = machine_obj.controller(controller).error_models(machine_obj.drives)
    source = read_run_program(program, machine_obj, tcp=tcp, dwell=dwell,
                              max_samples=max_samples, format=format,
                              tool_table=tool_table)
    # the highest feed of the search: the programmed one for an NC program, twice CL data's
    feed_options = feed_options.for_format(source.format)
    contour_tolerance = feed_options.tolerance
    feed_scale_max, feed_scale_min = feed_options.feed_scale_max, feed_options.feed_scale_min
    write_anyway = feed_options.write_anyway
    step(0, f"plan {program}")
    planned, passthrough = plan_run_program(source, machine_obj, dwell=dwell,
                                            corner_tolerance=corner_tolerance,
                                            corner_orientation_tolerance=(
                                                corner_orientation_tolerance),
                                            max_samples=max_samples)
    # a final rest long enough for the corrections to taper to zero (the compensated program
    # ends at its programmed end point): the controller holds the last command anyway
    end_rest = required_final_rest(models)
    as_planned = planned.n_samples
    planned = with_final_rest(planned, end_rest)
    final_rest_added = (planned.n_samples - as_planned) * planned.ts
    line = planned.line
    timings["plan"] = time.perf_counter() - start

    start = time.perf_counter()
    axis_limits = AxisLimits.from_machine(machine_obj)

    def round_progress(round_: int, message: str) -> None:
        step(1, f"{message}, round {round_}")

    feed = None
    if contour_tolerance is None:
        limited = compensate_within_limits(planned, machine_obj.kinematics, models,
                                           axis_limits, iterations=iterations,
                                           progress=round_progress, min_speed=min_speed)
        timings["compensate"] = time.perf_counter() - start
    else:
        programmed = planned
        if feed_scale_max != 1.0:
            step(1, f"plan {program} at {feed_scale_max:g} x the programmed feed")
            planned = with_final_rest(plan_run_program(
                source, machine_obj, dwell=dwell, corner_tolerance=corner_tolerance,
                corner_orientation_tolerance=corner_orientation_tolerance,
                max_samples=max_samples, feed_scale=feed_scale_max)[0], end_rest)
            line = planned.line
        def learned(limited):
            # a timing slowed beyond the learning's size is compensated without it
            if not can_learn(limited.reference, machine_obj):
                return limited
            return learn_on_ensemble(limited, machine_obj, learner, models, axis_limits,
                                     learn, ensemble=learning_ensemble)

        refine = learned if learn and can_learn(planned, machine_obj) else None
        feed = feed_within_tolerance(
            planned, machine_obj, controller, contour_tolerance, programmed=programmed,
            refine=refine, exempt_lines=_rapid_lines(source),
            feed_scale_max=feed_scale_max, min_speed=min(1.0, feed_scale_min / feed_scale_max),
            line=line, ensemble=MachineEnsemble() if ensemble is None else ensemble,
            progress=lambda message: step(1, message), models=models, limits=axis_limits,
            limits_min_speed=min_speed, iterations=iterations,
            where="line" if source.format == "gcode" else "row")
        timings["feed within tolerance"] = time.perf_counter() - start
        found = feed.compensated
        if not found.met and not write_anyway:
            raise ToleranceError(_tolerance_message(feed, feed_scale_min))
        # the compensated search's commands, with the slow-downs against the upper-bound plan
        limited = replace(found.limited, slowdowns=found.slowdowns,
                          planned_index=found.planned_index)
    if learn and feed is None:
        if can_learn(limited.reference, machine_obj):
            step(1, f"learn against the virtual machine ({learn} pass(es))")
            start = time.perf_counter()
            limited = learn_on_ensemble(
                limited, machine_obj, learner, models, axis_limits, learn,
                ensemble=learning_ensemble, planned=planned,
                # each command tried (a long program's segment by segment): learning on an
                # hour-long program runs for many minutes
                progress=lambda label, summary: step(
                    1, f"learn: {label}, worst draw tip max {summary['tip_max_um']:.3g} um"))
            timings["learn"] = time.perf_counter() - start

    step(2, f"virtual machine, uncompensated and compensated "
            f"({limited.reference.n_samples} samples each)")
    start = time.perf_counter()
    simulated = check_on_virtual_machine(limited.reference, limited.result.trajectory.q,
                                         machine, controller, workers=workers)
    timings["virtual machine (both)"] = time.perf_counter() - start
    checked = None
    if draws > 1:
        check_ensemble = replace(learning_ensemble, draws=draws)
        step(2, f"virtual machine, {draws - 1} more draw(s) of the machine, uncompensated "
                + ("(twice: its repeatability) " if check_ensemble.rerun_differs else "")
                + "and compensated")
        start = time.perf_counter()
        checked = check_on_draws(limited.reference, limited.result.trajectory.q, machine_obj,
                                 controller, simulated, line=limited.line,
                                 ensemble=check_ensemble)
        timings["virtual machine (draws)"] = time.perf_counter() - start
        worse = checked.worse_in_whole()
        if worse:
            warning(worse_in_whole_message(worse,
                                           learned=limited.result.learning is not None))

    step(3, "write G-code")
    start = time.perf_counter()
    commands = limited.result.trajectory
    learning = limited.result.learning
    info = ProgramInfo(machine=machine_obj.name, controller=controller,
                       method=f"contour pre-compensation within axis limits, passes "
                              f"{limited.result.iterations}"
                              + (f", learned against the virtual machine ({learn} pass(es)): "
                                 f"kept {learning.chosen}" if learning is not None else "")
                              + (f", fastest feed within {feed.tolerance.describe()} on the "
                                 "realistic virtual machine" if feed is not None else ""),
                       source=str(program))
    program_text = gcode_program(commands.t, commands.q, tolerance=tolerance, info=info,
                                 passthrough=passthrough, line=limited.line,
                                 axis_names=machine_obj.axis_names)
    timings["gcode"] = time.perf_counter() - start
    return RunResult(source=str(program), machine=machine_obj, controller=controller,
                     planned=planned, passthrough=passthrough, limited=limited,
                     simulated_before=simulated[0], simulated_after=simulated[1],
                     program=program_text, tolerance=tolerance, timings=timings,
                     stream=None if outputs is None else outputs.stream, feed=feed,
                     draws=checked, source_format=source.format,
                     final_rest_added=final_rest_added)


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


def can_learn(reference: Trajectory, machine_obj: Machine, *, whole: bool = False) -> bool:
    """Whether learning against the virtual machine can run on ``reference``; says why not,
    in one notice: the virtual machine runs at the servo period. Learning within the limits
    runs a trajectory of any length (segment by segment above
    :data:`~.compensation.pieces.AT_ONCE_SAMPLES` samples, :mod:`.compensation.segments`);
    ``whole``: learning that runs the whole trajectory at once (the unconstrained
    compensation's), refused above that many samples (compensated in pieces, linearly)."""
    if not machine_obj.at_servo_period(reference.ts):
        notice(f"no learning: the trajectory's sample period {reference.ts:g} s is not the "
               f"servo period {machine_obj.servo_period:g} s of the virtual machine")
        return False
    if whole and reference.n_samples > AT_ONCE_SAMPLES:
        notice(f"no learning: {reference.n_samples} samples are more than "
               f"{AT_ONCE_SAMPLES} (compensated in pieces)")
        return False
    return True


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


def learn_on_ensemble(limited: LimitedCompensation, machine_obj: Machine, controller: str,
                      models, limits: AxisLimits, passes: int, *,
                      ensemble: MachineEnsemble | None = None, progress=None,
                      planned: Trajectory | None = None) -> LimitedCompensation:
    """``limited`` improved by ``passes`` passes of learning within ``limits``
    (:func:`~.compensation.within_limits.learn_within_limits`) against the draws of
    ``ensemble`` of the realistic virtual machine running ``controller``
    (:func:`~.simulation.ensemble.ensemble_actual`): every choice is taken on the worst draw,
    and the command kept is nowhere worse than the uncompensated one on every draw, in whole
    and block by block. Above :data:`~.compensation.pieces.AT_ONCE_SAMPLES` samples, segment
    by segment (:func:`~.compensation.segments.learn_by_segments`). ``planned``: the
    trajectory ``limited`` was compensated from; where learning keeps the uncompensated
    command everywhere, that trajectory is returned as it was planned, without the slow-downs
    made for the corrections (:func:`~.compensation.within_limits.planned_if_uncompensated`).
    """
    if limited.reference.n_samples > AT_ONCE_SAMPLES:
        learned = learn_by_segments(
            limited, machine_obj.kinematics, models, limits,
            lambda t, start: ensemble_actual(t, machine_obj, controller, ensemble, start=start),
            passes,
            progress=progress)
    else:
        actual = ensemble_actual(limited.reference.t, machine_obj, controller, ensemble)
        learned = learn_within_limits(limited, machine_obj.kinematics, models, limits, actual,
                                      passes, progress=progress)
    if planned is None:
        return learned
    return planned_if_uncompensated(learned, planned, machine_obj.kinematics, models, limits)


def compensate_keeping_limits(traj: Trajectory, machine_obj: Machine, controller: str, *,
                              learn: int | LearningOptions = 0,
                              limits: LimitOptions = LimitOptions(), method: str = "contour",
                              iterations: int = 1, tol_linear: float | None = None,
                              tol_rotary: float | None = None, progress=None,
                              pass_progress=None, learning_progress=None
                              ) -> LimitedCompensation:
    """What ``compensate`` does by default, as ``run`` does: compensate ``traj`` within the
    machine's axis limits (slowing it down locally, never below ``limits.min_speed``, and
    compensating again where needed; :func:`~.compensation.within_limits.
    compensate_within_limits` with ``method``, ``iterations``, ``tol_linear``,
    ``tol_rotary``), then, for ``learn`` passes (a number or :class:`~.options.
    LearningOptions`), learn within them against the ensemble of the realistic virtual
    machine running the learning controller (default ``controller``;
    :func:`learn_on_ensemble`). The commands keep the limits, so ``export`` takes them.
    ``progress(round, message)`` reports the compensation rounds, ``pass_progress(pass,
    summary)`` the first round's passes, ``learning_progress(label, summary)`` each command
    learning tries."""
    learning = learning_options(learn)
    models = machine_obj.controller(controller).error_models(machine_obj.drives)
    axis_limits = AxisLimits.from_machine(machine_obj)
    # a final rest long enough for the corrections to taper to zero, so that the commands end
    # at the programmed end point (the controller holds the last command after them anyway)
    traj = with_final_rest(traj, required_final_rest(models))
    limited = compensate_within_limits(traj, machine_obj.kinematics, models, axis_limits,
                                       progress=progress,
                                       min_speed=limits.min_speed, method=method,
                                       iterations=iterations, tol_linear=tol_linear,
                                       tol_rotary=tol_rotary, pass_progress=pass_progress)
    if learning.passes:
        limited = learn_on_ensemble(limited, machine_obj, learning.controller or controller,
                                    models, axis_limits, learning.passes,
                                    ensemble=learning.ensemble, progress=learning_progress,
                                    planned=traj)
    return limited


def check_on_virtual_machine(reference: Trajectory, q_compensated: np.ndarray,
                             machine: str | Path, controller: str, *,
                             workers: int | None = 1) -> tuple[ContourErrors, ContourErrors]:
    """Contour errors of the uncompensated (``reference.q``) and the compensated commands on
    the realistic virtual machine (discrete controller, friction, feed-forward friction
    compensation), against ``reference``. The two runs are independent time loops: with
    ``workers`` >= 2 they run in two processes at once (None: see :func:`run_program`), else
    on :func:`~.parallel.jobs` threads of this one."""
    spec = str(Path(machine).resolve()) if Path(str(machine)).exists() else str(machine)
    runs = [(spec, controller, reference, q) for q in (reference.q, q_compensated)]
    if workers is None:
        workers = (min(2, os.cpu_count() or 1) if reference.n_samples >= PARALLEL_MIN_SAMPLES
                   else 1)
    if workers < 2:
        # on threads the machine is read once, for both runs
        machine_obj = load_machine(spec)
        return tuple(map_ordered(lambda run: _virtual_machine_errors(machine_obj, *run[1:]),
                                 runs))
    # forkserver: a clean process, whatever threads (pyarrow, BLAS) this one has started.
    context = multiprocessing.get_context("forkserver")
    with ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        futures = [pool.submit(_virtual_machine_errors, *run) for run in runs]
        return tuple(f.result() for f in futures)


def _virtual_machine_errors(machine: str | Machine, controller: str, reference: Trajectory,
                            q: np.ndarray) -> ContourErrors:
    # a spec in a worker process, which reads the machine itself; the Machine on threads
    machine_obj = machine if isinstance(machine, Machine) else load_machine(machine)
    q_act = realistic_actual(reference.t, machine_obj, controller)(q)
    # in pieces above AT_ONCE_SAMPLES: whole-program reference curves of a long program
    # were the peak of run's memory
    return contour_errors_program(reference, q_act, machine_obj.kinematics)


@dataclass(frozen=True)
class DrawCheck:
    """The uncompensated and the compensated commands on every draw of a machine ensemble
    (draw 0 the machine file's machine: ``RunResult.simulated_before`` / ``_after``), judged
    per source line (or window) as learning judges them (:func:`~.compensation.blocks.judge`).
    """

    ensemble: MachineEnsemble
    before: Judgement
    after: Judgement
    starts: np.ndarray
    #: The uncompensated commands run again on the same machines (their encoder noise
    #: re-drawn), or None where the draws have no noise; ``before`` then carries each block's
    #: repeatability (:func:`~.compensation.blocks.with_repeatability`).
    again: Judgement | None = None

    def reductions(self, quantity: str = "tip_max") -> np.ndarray:
        """Per draw, the share of the uncompensated error the compensated commands removed
        (1 = all), of ``quantity`` (``tip_max``, ``tip_mean``, ``ori_max``, ``ori_mean``)."""
        key = {"tip_max": "tip_max_um", "tip_mean": "tip_mean_um", "ori_max": "ori_max_mrad",
               "ori_mean": "ori_mean_mrad"}[quantity]
        before = np.array([s[key] for s in self.before.summaries])
        after = np.array([s[key] for s in self.after.summaries])
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(before > 0, 1.0 - after / before, 0.0)

    def worse_blocks(self) -> np.ndarray:
        """Indices of the blocks where the compensated commands' worst draw exceeds the
        uncompensated commands' worst draw by more than the block margins and the
        uncompensated commands' repeatability there."""
        from .compensation.blocks import worse_blocks

        return np.flatnonzero(worse_blocks(self.after, self.before))

    def worse_blocks_without_repeatability(self) -> np.ndarray:
        """:meth:`worse_blocks` by the block margins alone."""
        from .compensation.blocks import worse_blocks

        return np.flatnonzero(worse_blocks(self.after, self.before.without_repeatability()))

    def self_worse_blocks(self) -> np.ndarray:
        """Indices of the blocks where the uncompensated commands run again are worse than
        themselves by the block margins alone: how many blocks the comparison counts that no
        command decides (empty without a rerun)."""
        from .compensation.blocks import worse_blocks

        if self.again is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(worse_blocks(self.again, self.before.without_repeatability()))

    def worse_in_whole(self) -> tuple[str, ...]:
        """The quantities (``tip max``, ``orientation max``) whose worst draw is above the
        uncompensated commands' worst draw, over both their runs where they ran twice, by more
        than the block margins (or not finite): the compensated program is worse where it is
        worst, and not by the machine's scatter from run to run."""
        from .compensation.blocks import ORIENTATION_MARGIN, TIP_MARGIN, margin_bound

        runs = [self.before] + ([self.again] if self.again is not None else [])
        worse = []
        for label, key, margin in (("tip max", "tip_max_um", 1e3 * TIP_MARGIN),
                                   ("orientation max", "ori_max_mrad",
                                    1e3 * ORIENTATION_MARGIN)):   # um and mrad
            before = max(s[key] for judged in runs for s in judged.summaries)
            after = max(s[key] for s in self.after.summaries)
            if not after <= margin_bound(before, margin):
                worse.append(label)
        return tuple(worse)

    def table(self, where: str = "line", learned: bool = False) -> list[str]:
        """Lines of the end-of-run table: median and worst over the draws (``learned``: the
        commands were learned, for the warning's advice)."""
        lines = [f"on {self.ensemble.describe()}:"]
        keys = ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")
        for commands, judged in (("uncompensated", self.before), ("compensated", self.after)):
            values = np.array([[s[key] for key in keys] for s in judged.summaries])
            for label, row in (("median", np.median(values, axis=0)),
                               ("worst", values.max(axis=0))):
                lines.append(f"{commands + ' ' + label:<22}{row[0]:10.3f}{row[1]:10.3f}"
                             f"{row[2]:10.4f}{row[3]:10.4f}")
        for label, quantity in (("tip", "tip"), ("orientation", "ori")):
            r_max = 100 * self.reductions(f"{quantity}_max")
            r_mean = 100 * self.reductions(f"{quantity}_mean")
            lines.append(f"  {label} reduction, median / worst draw: max "
                         f"{np.median(r_max):.1f} / {r_max.min():.1f} %, mean "
                         f"{np.median(r_mean):.1f} / {r_mean.min():.1f} %")
        from .compensation.blocks import MARGINS

        repeatable = self.before.tip_repeatability is not None
        if repeatable:
            tip = 1e3 * float(np.max(self.before.tip_repeatability, initial=0.0))
            ori = 1e6 * float(np.max(self.before.orientation_repeatability, initial=0.0))
            lines.append(f"  uncompensated run again on the same machines (encoder noise "
                         f"re-drawn): a {where}'s max changed by up to {tip:.3g} um / "
                         f"{ori:.3g} urad, worse than itself beyond {MARGINS} on "
                         f"{self.self_worse_blocks().size} {where}(s)")
        worse = self.worse_blocks().size
        margins = f"beyond {MARGINS}" + (f" and the {where}'s repeatability" if repeatable
                                         else "")
        plain = self.worse_blocks_without_repeatability().size
        lines.append(f"  compensated worse than uncompensated (worst draw against worst draw, "
                     f"{margins}) on {worse} {where}(s)"
                     + (f" ({plain} by the margins alone)" if plain != worse else "")
                     if worse or plain else
                     f"  compensated nowhere worse than uncompensated on the worst draw "
                     f"({MARGINS} per {where})")
        worse_in_whole = self.worse_in_whole()
        if worse_in_whole:
            lines.append("  warning: " + worse_in_whole_message(worse_in_whole, learned))
        return lines


def worse_in_whole_message(quantities: Sequence[str], learned: bool = False) -> str:
    """The warning where the compensated program's worst draw is worse where it is worst
    (:meth:`DrawCheck.worse_in_whole`)."""
    return (f"the compensated program's {' and '.join(quantities)} on its worst draw is above "
            "the uncompensated program's (friction at a stop or reversal)"
            + (": the draws differ from those learning decided on (--draws, the learning "
               "controller)" if learned else
               ": --learn N keeps a command that is nowhere worse on the draws"))


def errors_on_draws(reference: Trajectory, q: np.ndarray, machine_obj: Machine,
                    controller: str, ensemble: MachineEnsemble,
                    nominal: ContourErrors | None = None):
    """The contour errors of the commands ``q`` against ``reference`` on each draw of
    ``ensemble`` (on the realistic virtual machine), a generator: the draws run on
    :func:`~.parallel.jobs` threads, with that many draws' encoder noise and motion in memory
    at once (a long program). Draw 0 of an ensemble whose first draw is the machine file's
    machine is ``nominal`` where given (its errors there, already simulated)."""
    return map_ordered(_DrawErrors(reference, machine_obj, controller),
                       [(q, ensemble, draw, nominal) for draw in range(ensemble.draws)])


class _DrawErrors:
    """One draw's contour errors of a command, a task of :func:`errors_on_draws` (an object,
    not a closure: the same task for every command and ensemble of a check)."""

    def __init__(self, reference: Trajectory, machine_obj: Machine, controller: str):
        self.reference, self.machine, self.controller = reference, machine_obj, controller
        self.rotary = [d.is_rotary for d in machine_obj.drives]

    def __call__(self, task) -> ContourErrors:
        from .simulation.virtual_machine import REALISTIC, simulate

        q, ensemble, draw, nominal = task
        if draw == 0 and ensemble.nominal and nominal is not None:
            return nominal
        check_signals()
        q_act = simulate(self.reference.t, q, self.machine, self.controller, **REALISTIC,
                         **ensemble.option(draw, self.reference.n_samples, self.rotary)).q_act
        return contour_errors_program(self.reference, q_act, self.machine.kinematics)


def check_on_draws(reference: Trajectory, q_compensated: np.ndarray, machine_obj: Machine,
                   controller: str, nominal: tuple[ContourErrors, ContourErrors], *,
                   line: np.ndarray | None = None,
                   ensemble: MachineEnsemble | None = None) -> DrawCheck:
    """Both commands (``reference.q`` and ``q_compensated``) on every draw of ``ensemble``
    (default :class:`MachineEnsemble` ()) (:func:`errors_on_draws`): draw 0, the machine
    file's machine, is ``nominal`` (their errors there, already simulated; no encoder, so a
    rerun is the same run). The draws of all the runs (uncompensated, its rerun where the
    encoder differs, compensated) go through one queue of :func:`~.parallel.jobs` threads, so
    the cores stay busy from one run's draws to the next."""
    from .compensation.blocks import block_starts, judge, with_repeatability

    ensemble = MachineEnsemble() if ensemble is None else ensemble
    starts = block_starts(reference.n_samples, reference.ts, line)
    runs = [(reference.q, ensemble, nominal[0])]
    if ensemble.rerun_differs:
        runs.append((reference.q, ensemble.rerun(), nominal[0]))
    runs.append((q_compensated, ensemble, nominal[1]))
    errors = map_ordered(_DrawErrors(reference, machine_obj, controller),
                         [(q, machines, draw, errors_nominal)
                          for q, machines, errors_nominal in runs
                          for draw in range(machines.draws)])
    # each judgement takes its run's draws off the one ordered queue
    judged = [judge(islice(errors, machines.draws), starts) for _, machines, _ in runs]
    before, after = judged[0], judged[-1]
    again = judged[1] if ensemble.rerun_differs else None
    if again is not None:
        before = with_repeatability(before, again)
    return DrawCheck(ensemble=ensemble, before=before, after=after, starts=starts,
                     again=again)


def write_run_outputs(result: RunResult, outputs: RunOutputs,
                      inputs: Sequence[str | Path]) -> list[Path]:
    """Write the program and the optional stream and command files as one set
    (:class:`~precontour.files.OutputSet`: all replace the old files, or none does; inside
    an outer set, e.g. with the report, with that one)."""
    commands = result.commands
    final = check_limits(commands.q, commands.ts, AxisLimits.from_machine(result.machine))
    if not final.ok:  # compensate_within_limits guarantees it; this guards the writing
        raise MachineLimitError("refusing to write commands beyond the machine's limits: "
                                + final.format())
    info = ProgramInfo(machine=result.machine.name, controller=result.controller,
                       method="contour pre-compensation within axis limits",
                       source=result.source)
    with outputs.output_set(inputs):
        written = [write_text(outputs.program, result.program.text, inputs=inputs)]
        if outputs.stream is not None:
            written.append(write_text(outputs.stream,
                                      halstreamer_lines(commands.q, commands.ts, info=info),
                                      inputs=inputs))
        if outputs.commands is not None:
            # with the source line of each sample, where known: what the table's largest
            # errors name can be looked up in it
            table = commands if result.limited.line is None else replace(
                commands, line=result.limited.line)
            written.append(write_columns(outputs.commands,
                                         trajectory_columns(table, result.machine.axis_names),
                                         inputs=inputs))
    return written


@dataclass(frozen=True)
class ExportResult:
    """What ``export`` wrote."""

    path: Path
    format: str
    n_samples: int
    n_blocks: int | None


def export_format(path: Path, format: str | None) -> str:
    """The export format: given, or from the output's extension."""
    if format is not None:
        if format not in EXPORT_FORMATS:
            raise InputError(f"unknown format {format!r}; use one of {', '.join(EXPORT_FORMATS)}",
                             field="format")
        return format
    suffix = path.suffix.lower()
    if suffix in GCODE_SUFFIXES:
        return "gcode"
    if suffix in SUPPORTED_SUFFIXES:
        return suffix[1:]
    raise InputError(f"cannot tell the format from the extension {suffix or '(none)'!r}; "
                     "give --format", source=str(path))


def export_commands(commands_path: str | Path, output: str | Path, *, format: str | None = None,
                    machine: str | Path, controller: str = "",
                    tolerance: np.ndarray | None = None) -> ExportResult:
    """Write a command file (``t,X,Y,Z,A,C[,...]``) as G-code, a halstreamer file or a table.

    ``machine`` (built-in name or machine file) has no default: its limits decide what may be
    written. G-code and halstreamer files are programs a machine runs: the commands must keep the
    machine's limits (checked first; :class:`~precontour.errors.MachineLimitError` names the
    worst excess otherwise), and a halstreamer file needs samples at the servo period.
    """
    output = Path(output)
    format = export_format(output, format)
    inputs = [commands_path] + ([machine] if Path(str(machine)).exists() else [])
    suffixes = {"gcode": GCODE_SUFFIXES, "halstreamer": None}.get(format, (f".{format}",))
    check_output_path(output, inputs=inputs, suffixes=suffixes)
    tolerance = gcode_tolerances() if tolerance is None else np.asarray(tolerance, dtype=float)
    machine_obj = load_machine(machine)
    traj = read_trajectory(commands_path, axis_names=machine_obj.axis_names)
    if format not in ("gcode", "halstreamer"):
        write_columns(output, trajectory_columns(traj, machine_obj.axis_names), inputs=inputs)
        return ExportResult(output, format, traj.n_samples, None)
    if controller:
        machine_obj.controller(controller)  # an unknown name is an error, as elsewhere
    limits = AxisLimits.from_machine(machine_obj)
    # each axis within its travel (the tilt axis within +-180 deg at most), named by row
    check_travel(traj.q, limits, source=str(commands_path), axis_names=machine_obj.axis_names)
    check = check_limits(traj.q, traj.ts, limits, t0=traj.t[0])
    if not check.ok:
        raise MachineLimitError(f"{commands_path}: the commands exceed the machine's limits "
                                f"({check.format()}); `precontour run` slows such places down "
                                "and compensates again")
    info = ProgramInfo(machine=machine_obj.name, controller=controller,
                       method="exported commands", source=str(commands_path))
    if format == "halstreamer":
        if not machine_obj.at_servo_period(traj.ts):
            raise InputError(f"sampled every {traj.ts:.6g} s, but a halstreamer file needs one "
                             f"line per servo period ({machine_obj.servo_period:g} s of "
                             f"{machine_obj.name})", source=str(commands_path), field="t")
        write_text(output, halstreamer_lines(traj.q, traj.ts, info=info), inputs=inputs)
        return ExportResult(output, format, traj.n_samples, None)
    program = gcode_program(traj.t, traj.q, tolerance=tolerance, info=info,
                            axis_names=machine_obj.axis_names)
    if "\nG1 " not in program.text:
        # dwells only: a program the G-code reader (and so run and trajectory) refuses
        raise InputError("the commands do not move by more than the written decimals (1e-5 mm, "
                         "1e-6 deg): no motion to write as G-code", source=str(commands_path))
    write_text(output, program.text, inputs=inputs)
    return ExportResult(output, format, traj.n_samples, program.n_blocks)


__all__ = ["EXPORT_FORMATS", "LargestError", "RunOutputs", "RunProgram", "RunResult",
           "ExportResult", "check_run_outputs", "compensate_keeping_limits", "largest_error",
           "export_commands", "export_format", "learn_on_ensemble", "load_program_trajectory",
           "plan_run_program", "read_run_program", "run_program", "write_run_outputs"]
