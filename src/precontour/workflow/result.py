"""What ``run`` gives back: where its outputs go (:class:`RunOutputs`, checked before
anything is computed), and the result (:class:`RunResult`: the commands, the predicted and
simulated contour errors, the largest errors and the lines made worse, and its table)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..compensation.within_limits import LimitedCompensation
from ..files import OutputSet
from ..machine.machine_file import Machine
from ..planning.tolerance import FeedWithinTolerance
from ..prediction.contour import ContourErrors, ErrorSummary
from ..tables import SUPPORTED_SUFFIXES
from ..toolpath import PROGRAM_FORMATS, toolpath_format
from ..toolpath.writers import GcodeProgram
from ..trajectory.sampled import Trajectory
from .checks import DrawCheck
from .program import GCODE_SUFFIXES


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
class RunSummary:
    """What :meth:`RunResult.summary` gives: the contour errors (um, mrad) of the
    uncompensated (``before``) and compensated (``after``) commands on the realistic virtual
    machine, the program's duration against its plan (s), the source lines worse than
    uncompensated, and the G-code blocks written."""

    before: ErrorSummary
    after: ErrorSummary
    duration: float
    planned_duration: float
    lines_worse: int
    blocks: int

    def reduction(self, key: str = "tip_max_um") -> float:
        """The fraction of ``before[key]`` that compensation removed (1: all; < 0: worse)."""
        return 1.0 - self.after[key] / self.before[key] if self.before[key] > 0 else 0.0


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
    draws: DrawCheck | None = None
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
        from ..compensation.blocks import (ORIENTATION_MARGIN, TIP_MARGIN, block_starts, judge,
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
        """The end-of-run table: contour errors before and after, duration, blocks
        (:func:`precontour.reports.run_table.run_table`)."""
        # the text is the report stage's (tests/test_layout.py allows a result's table())
        from ..reports.run_table import run_table

        return run_table(self)

    def summary(self) -> RunSummary:
        """The run's headline numbers on the realistic virtual machine (the machine file's
        draw; the median and worst draws: :attr:`draws`)."""
        before, after = self.simulated_before, self.simulated_after
        return RunSummary(before=before.summary(), after=after.summary(),
                          duration=float(self.commands.duration),
                          planned_duration=float(self.planned.duration
                                                 - self.final_rest_added),
                          lines_worse=len(self.worse_lines()),
                          blocks=int(self.program.n_blocks))

    def plot(self):
        """The contour errors on the realistic virtual machine before and after, their
        envelopes against time (:func:`precontour.reports.run_report.
        plot_contour_envelope`); returns the figure."""
        from ..reports.run_report import plot_contour_envelope

        return plot_contour_envelope(self)

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
