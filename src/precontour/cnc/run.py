"""Compensation at the controller's own timing: ``run PROGRAM --timing TRACE [--learn-from
TRACE]``.

:func:`compensate_at_timing` takes the controller's trace of the uncompensated program (the
timing, the reference path, and when it has actual positions the uncompensated errors),
computes the commands (predicted from the identified model, or learned from a later trace of
the machine, :mod:`.learn`), and gives the program's own blocks with corrected end points
(:mod:`.blocks`). :func:`run_at_timing` does that and writes the outputs as one set;
:func:`timing_trace` reads the timing from a file or records it on LinuxCNC
(``linuxcnc:DIR``, a configuration of ``precontour linuxcnc-config``).

Learning never keeps a correction on a program line that the trace learned from shows worse
than the uncompensated run (beyond :data:`~precontour.compensation.blocks.TIP_MARGIN` /
:data:`~precontour.compensation.blocks.ORIENTATION_MARGIN` or
:data:`~precontour.compensation.blocks.RELATIVE_MARGIN` of the line's uncompensated max, or
beyond the repeatability of two uncompensated traces when a second one is given): such lines
learn from the uncompensated run (the timing trace, which then needs actual positions)
instead of from the correction that made them worse.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..compensation.blocks import ORIENTATION_MARGIN, RELATIVE_MARGIN, TIP_MARGIN
from ..errors import InputError
from ..files import OutputSet, atomic_write
from ..tables import SUPPORTED_SUFFIXES, write_columns
from .blocks import CorrectedProgram, block_starts, correct_program
from .learn import (Measured, commands_learned_from, learned_commands, measure_trace,
                    reference_path)
from .trace import (ControllerTrace, degrees_per_unit, read_controller_trace,
                    trace_from_recording)

__all__ = ["LINUXCNC_PREFIX", "OVERLAY_START", "TimingRun", "block_lateness",
           "compensate_at_timing", "overlay_offsets", "overlay_program",
           "line_maxima",
           "record_on_linuxcnc", "run_at_timing", "timing_trace", "worse_lines",
           "write_trace"]

#: A timing given as ``linuxcnc:DIR`` is recorded by running the program on the LinuxCNC
#: configuration DIR headless.
LINUXCNC_PREFIX = "linuxcnc:"
#: The words ``run --overlay`` puts at the start of the program's first move: the digital
#: output that starts the overlay streamer, synchronised with the start of that move.
OVERLAY_START = "M62 P0 (precontour: the overlay starts with this move)"
#: Servo periods by which the overlay's first sample follows the start of the first move as
#: the timing trace records it: -1, measured on LinuxCNC 2.9 (the recorded overlay matched
#: the file to 0.3 um shifted one period earlier, and to 4.9 um unshifted: the streamer
#: emits in the period before the one whose program line the recorder sees change).
OVERLAY_LEAD = -1
#: Seconds over which an overlay file returns to 0 after the program (and ends there).
OVERLAY_TAIL = 0.5
#: Seconds over which the overlay fades in from the first move's start: the approach rapid
#: (not compensated) may leave the axes tens of micrometres behind there, and a step of the
#: offset would kick the loops.
OVERLAY_RAMP = 0.1
#: Where :func:`compensate_at_timing` puts the correction.
INTO = ("blocks", "overlay")


@dataclass(frozen=True)
class TimingRun:
    """What :func:`compensate_at_timing` gives.

    Attributes
    ----------
    program : CorrectedProgram or None
        The program's own blocks with corrected end points (None for an overlay).
    commands : ndarray, shape (N, 5)
        The commands the blocks were fitted to, at the timing trace's samples (mm, rad).
    timing : ControllerTrace
        The controller's trace of the uncompensated program.
    method : str
        ``"predicted"`` (the identified model's compensation) or ``"learned"`` (from a trace).
    uncompensated : Measured or None
        The timing trace's own errors, when it has actual positions.
    learned_from : Measured or None
        The errors of the trace learned from.
    reverted_lines : tuple of int
        Program lines the trace learned from shows worse than the uncompensated run: the
        correction it carried there is not kept, they learn from the uncompensated run.
    move_lines : ndarray of int
        Source line of each of the program's moves.
    """

    program: CorrectedProgram | None
    commands: np.ndarray
    timing: ControllerTrace
    method: str
    uncompensated: Measured | None = None
    learned_from: Measured | None = None
    reverted_lines: tuple[int, ...] = ()
    learned_source: str = ""
    late_periods: np.ndarray | None = None
    move_lines: np.ndarray | None = None

    @property
    def late_blocks(self) -> int:
        """Blocks the learned-from run started more than one servo period off the timing
        trace's (from the first block's start), or 0 without one."""
        if self.late_periods is None:
            return 0
        return int(np.sum(np.abs(self.late_periods) > 1))

    def table(self) -> str:
        """What ``run --timing`` prints: the measured errors, and what the blocks carry."""
        rows = [f"timing: {self.timing.source} ({self.timing.n_samples} periods of "
                f"{self.timing.period * 1e3:g} ms)",
                "commands: " + ("predicted by the model (" + "the controller's timing kept)"
                                if self.method == "predicted" else
                                f"learned from {self.learned_source}"),
                "measured on the machine, from 0.3 s after the first move to the end of the "
                "commanded motion:",
                f"{'':32s} {'tip max um':>10s} {'tip mean um':>11s} "
                f"{'ori max mrad':>12s} {'ori mean mrad':>13s}"]
        for label, measured in (("uncompensated (timing trace)", self.uncompensated),
                                ("learned from", self.learned_from)):
            if measured is None:
                continue
            e = measured.summary()
            rows.append(f"{label:32s} {e.tip_max_um:10.3f} {e.tip_mean_um:11.4f} "
                        f"{e.ori_max_mrad:12.4f} {e.ori_mean_mrad:13.5f}")
        if self.uncompensated is None and self.learned_from is None:
            rows.append("  (no actual positions in the traces: nothing measured)")
        p = self.program
        if p is None:
            rows.append("overlay: the correction at the servo rate, beside the program as "
                        "written")
        else:
            share = 1.0 - float(np.sum(p.residual_rms ** 2)
                                / max(np.sum(p.needed_rms ** 2), 1e-300))
            rows.append(f"blocks: {p.lines.size} straight feed moves corrected, {p.fixed} kept "
                        f"as written (expressions, several moves on a line); the blocks carry "
                        f"{100 * max(share, 0.0):.1f} % of the correction's square over the "
                        "program")
        if self.late_periods is not None and self.late_periods.size:
            rows.append(f"timing of the learned-from run: {self.late_blocks} of "
                        f"{self.late_periods.size} blocks started more than one servo period "
                        f"off the timing trace's (largest {int(np.abs(self.late_periods).max())}"
                        " periods)")
        if self.reverted_lines:
            shown = ", ".join(str(n) for n in self.reverted_lines[:10])
            more = (f" and {len(self.reverted_lines) - 10} more"
                    if len(self.reverted_lines) > 10 else "")
            rows.append(f"learned from the uncompensated run on {len(self.reverted_lines)} "
                        f"line(s) the learned-from trace shows worse: {shown}{more}")
        return "\n".join(rows)


def line_maxima(measured: Measured) -> dict[int, tuple[float, float]]:
    """Per program line: the max tip (mm) and orientation (rad) contour error on it."""
    lines = measured.line
    order = np.argsort(lines, kind="stable")
    sorted_lines = lines[order]
    edges = np.flatnonzero(np.diff(sorted_lines)) + 1
    starts = np.concatenate([[0], edges])
    tip = np.maximum.reduceat(measured.errors.tip[order], starts)
    ori = np.maximum.reduceat(measured.errors.orientation[order], starts)
    return {int(sorted_lines[s]): (float(a), float(b)) for s, a, b in zip(starts, tip, ori)}


def worse_lines(run: Measured, baseline: Measured,
                repeat: Measured | None = None) -> list[int]:
    """Program lines on which ``run`` is worse than ``baseline`` (tip or orientation max)
    beyond the margins, or beyond the difference between ``baseline`` and ``repeat`` (a
    second uncompensated trace) on that line where that is larger."""
    ours, base = line_maxima(run), line_maxima(baseline)
    again = line_maxima(repeat) if repeat is not None else {}
    worse = []
    for line, (tip, ori) in ours.items():
        if line <= 0 or line not in base:    # 0: after the program's end
            continue
        b_tip, b_ori = base[line]
        r_tip, r_ori = again.get(line, (b_tip, b_ori))
        tip_margin = max(TIP_MARGIN, RELATIVE_MARGIN * b_tip, abs(r_tip - b_tip))
        ori_margin = max(ORIENTATION_MARGIN, RELATIVE_MARGIN * b_ori, abs(r_ori - b_ori))
        if tip > b_tip + tip_margin or ori > b_ori + ori_margin:
            worse.append(line)
    return worse


def compensate_at_timing(servo, program: str | os.PathLike, timing: ControllerTrace, *,
                         learn_from: ControllerTrace | None = None,
                         repeat: ControllerTrace | None = None, method: str = "contour",
                         tcp: bool = False, into: str = "blocks") -> TimingRun:
    """The program's own blocks compensated at the timing of ``timing`` (the controller's
    trace of the program as written).

    Without ``learn_from`` the commands are the model's compensation of the traced commands
    (``method``: ``"contour"`` or ``"tracking"``, as :func:`precontour.compensate`, without
    re-timing: the controller's timing is kept). With it, they are learned from that trace
    (a run of the program, uncompensated or compensated, with actual positions; see
    :mod:`.learn`); ``repeat``, a second uncompensated trace, sets the repeatability against
    which a line counts as worse. ``into``: ``"blocks"``, the program's own blocks with
    corrected end points, or ``"overlay"``, the commands only (for :func:`overlay_offsets`;
    no blocks are fitted)."""
    from ..toolpath import read_program

    if into not in INTO:
        raise ValueError(f"into must be one of {INTO}, got {into!r}")
    machine = servo.machine
    moves = read_program(program, machine, tcp=tcp).programmed
    if timing.line is None:
        raise InputError("the timing trace has no program line column (line): it cannot be "
                         "matched to the program's blocks", source=timing.source,
                         field="line")
    uncompensated = path = None
    if timing.actual is not None or learn_from is not None:
        path = reference_path(servo, timing)        # built once: every measure uses it
    if timing.actual is not None:
        uncompensated = measure_trace(servo, timing, timing, moves.line, path)
    reverted: tuple[int, ...] = ()
    measured = None
    if learn_from is None:
        commands = _predicted(servo, timing, method)
        kind = "predicted"
    else:
        commands, measured = learned_commands(servo, timing, learn_from, moves.line,
                                              path=path)
        kind = "learned"
        if uncompensated is not None:
            again = (measure_trace(servo, timing, repeat, moves.line, path)
                     if repeat is not None else None)
            lines = worse_lines(measured, uncompensated, again)
            if lines:
                # the correction the trace carried there is not kept: those lines learn
                # from the uncompensated run instead
                restart = commands_learned_from(servo, timing, uncompensated)
                on = np.isin(timing.line, lines)
                commands[on] = restart[on]
                reverted = tuple(lines)
    late = None
    if learn_from is not None and learn_from.line is not None:
        late = block_lateness(timing, learn_from, moves.line)
    corrected = (correct_program(program, machine, timing, commands, tcp=tcp)
                 if into == "blocks" else None)
    return TimingRun(program=corrected, commands=commands, timing=timing, method=kind,
                     uncompensated=uncompensated, learned_from=measured,
                     reverted_lines=reverted,
                     learned_source=learn_from.source if learn_from is not None else "",
                     late_periods=late, move_lines=moves.line)


def block_lateness(timing: ControllerTrace, run: ControllerTrace, move_lines) -> np.ndarray:
    """Per block both traces reach: how many servo periods later ``run`` started it than
    ``timing`` did, counted from each trace's first block (LinuxCNC's program line changes
    in the period its planner starts the block)."""
    reference = block_starts(timing.line, np.asarray(move_lines))
    other = block_starts(run.line, np.asarray(move_lines))
    both = (reference >= 0) & (other >= 0)
    if not np.any(both):
        return np.zeros(0, dtype=np.int64)
    reference, other = reference[both], other[both]
    return (other - other[0]) - (reference - reference[0])


def _predicted(servo, timing: ControllerTrace, method: str) -> np.ndarray:
    from ..compensation.pieces import compensate_program

    # at the trace's own timing (the overlay adds to the commands the controller plans), its
    # corrections tapered within the trace's final rest
    commands = compensate_program(servo, timing.reference(servo.kinematics),
                                  method=method).trajectory.q
    if commands.shape != timing.command.shape:   # pragma: no cover - compensate_program keeps it
        raise RuntimeError("the compensation changed the trace's timing")
    return commands


def overlay_offsets(timing: ControllerTrace, commands: np.ndarray, move_lines) -> np.ndarray:
    """The overlay file's rows: ``commands`` minus the timing trace's commands, per joint in
    LinuxCNC's units (mm, degrees), one per servo period from the first move's start (the
    program's ``M62 P0``), then :data:`OVERLAY_TAIL` of zeros."""
    starts = block_starts(timing.line, np.asarray(move_lines))
    if not np.any(starts >= 0):
        raise InputError("the timing trace never executes one of the program's moves: the "
                         "overlay cannot be matched to it", source=timing.source, field="line")
    first = int(starts[starts >= 0][0]) + OVERLAY_LEAD
    offsets = (np.asarray(commands) - timing.command)[first:] * degrees_per_unit()
    # faded in (C1) over OVERLAY_RAMP: the overlay starts from 0 whatever the approach left
    ramp = min(int(round(OVERLAY_RAMP / timing.period)), offsets.shape[0])
    if ramp > 1:
        x = np.linspace(0.0, 1.0, ramp)
        offsets[:ramp] *= (x * x * (3.0 - 2.0 * x))[:, None]
    # and back to 0 over the tail
    count = int(round(OVERLAY_TAIL / timing.period))
    x = np.linspace(1.0, 0.0, count)
    tail = offsets[-1] * (x * x * (3.0 - 2.0 * x))[:, None]
    return np.vstack([offsets, tail])


def overlay_program(text: str, first_line: int) -> str:
    """``text`` with :data:`OVERLAY_START` on line ``first_line`` (1-based: the program's
    first move), after its block number if it has one: the line numbers stay the program's,
    so that traces of the overlaid program match its blocks."""
    lines = text.splitlines(keepends=True)
    raw = lines[first_line - 1]
    number = re.match(r"\s*(?:/\s*)?[Nn]\s*\d+\s*", raw)
    at = number.end() if number else len(raw) - len(raw.lstrip())
    lines[first_line - 1] = raw[:at] + OVERLAY_START + " " + raw[at:]
    return "".join(lines)


def timing_trace(source: str | os.PathLike | ControllerTrace, program, machine, *,
                 fmt: str | None = None, columns=None, angles: str | None = None,
                 timeout: float = 3600.0, overlay=None) -> ControllerTrace:
    """The controller's trace of ``program``: ``source`` as it is (a trace), read from a file
    (:func:`~.trace.read_controller_trace`), or, for ``linuxcnc:DIR``, recorded by running
    ``program`` on the LinuxCNC configuration DIR headless."""
    if isinstance(source, ControllerTrace):
        return source
    text = str(source)
    if text.startswith(LINUXCNC_PREFIX):
        from ..linuxcnc.run import LinuxcncFailed, LinuxcncUnavailable, run_gcode

        config = Path(text[len(LINUXCNC_PREFIX):])
        if not (config / "headless.ini").is_file():
            raise InputError("not a configuration of precontour linuxcnc-config (no "
                             "headless.ini)", source=str(config))
        try:
            recording = run_gcode(config, program, timeout=timeout, overlay=overlay)
        except (LinuxcncUnavailable, LinuxcncFailed) as exc:
            raise InputError(f"LinuxCNC could not record the program: {exc}",
                             source=str(config)) from None
        return trace_from_recording(recording, source=f"{text} ({Path(program).name})")
    if angles is None:
        angles = "rad" if Path(text).suffix.lower() in SUPPORTED_SUFFIXES else "deg"
    return read_controller_trace(text, machine, fmt=fmt, columns=columns, angles=angles)


def record_on_linuxcnc(config: str | os.PathLike, program: str | os.PathLike, machine,
                       output: str | os.PathLike, *, overlay=None) -> ControllerTrace:
    """Run ``program`` on the LinuxCNC configuration ``config`` headless and write its trace
    (:func:`write_trace`) to ``output``; ``machine``: a name, file or Machine (the axes'
    letters); ``overlay``: a ``run --overlay`` file to stream beside the program (its
    commands are then the motion controller's plus the overlay)."""
    from ..machine import Machine, load_machine

    machine = machine if isinstance(machine, Machine) else load_machine(machine)
    outputs = OutputSet([program, overlay])
    outputs.file(output)
    trace = timing_trace(f"{LINUXCNC_PREFIX}{config}", program, machine, overlay=overlay)
    with outputs:
        write_columns(output, _trace_columns(trace, tuple(machine.axis_names)))
    return trace


def write_trace(trace: ControllerTrace, path: str | os.PathLike, *, inputs=()) -> Path:
    """Write ``trace`` as a servo log table (``t``, the axes' commands, ``_act`` columns when
    the trace has actual positions, ``line``; mm and rad), which ``identify``,
    ``run --timing`` and ``run --learn-from`` read."""
    return write_columns(path, _trace_columns(trace), inputs=inputs)


def _trace_columns(trace: ControllerTrace, axis_names=("X", "Y", "Z", "A", "C")) -> dict:
    columns = {"t": trace.t - trace.t[0]}
    for i, letter in enumerate(axis_names):
        columns[letter] = trace.command[:, i]
    if trace.actual is not None:
        for i, letter in enumerate(axis_names):
            columns[f"{letter}_act"] = trace.actual[:, i]
    if trace.line is not None:
        columns["line"] = trace.line.astype(float)
    return columns


def run_at_timing(servo, program: str | os.PathLike, timing, output: str | os.PathLike, *,
                  learn_from=None, repeat=None, commands_output=None, tcp: bool = False,
                  method: str = "contour", trace_output=None, fmt: str | None = None,
                  columns=None, angles: str | None = None,
                  overlay_output=None) -> TimingRun:
    """:func:`compensate_at_timing` with the traces given as files (or ``linuxcnc:DIR``
    for the timing) and the outputs written as one set: the corrected program ``output``,
    optionally the commands (``commands_output``, a table at the timing's samples) and the
    timing trace recorded (``trace_output``, for ``linuxcnc:DIR``). With ``overlay_output``
    the correction goes to LinuxCNC as a servo-rate overlay instead of into the blocks: that
    file (``halstreamer`` rows, one per servo period from the first move) and, as ``output``,
    the program as written with :data:`OVERLAY_START` on its first move's line. Every output
    is checked before anything is computed."""
    program = Path(program)
    inputs = [program] + [Path(p) for p in (timing, learn_from, repeat)
                          if isinstance(p, (str, os.PathLike))
                          and not str(p).startswith(LINUXCNC_PREFIX)]
    outputs = OutputSet(inputs)
    outputs.file(output)
    if commands_output is not None:
        outputs.file(commands_output)
    if trace_output is not None:
        outputs.file(trace_output)
    if overlay_output is not None:
        outputs.file(overlay_output)
    machine = servo.machine
    trace = timing_trace(timing, program, machine, fmt=fmt, columns=columns, angles=angles)
    learned = (timing_trace(learn_from, program, machine, fmt=fmt, columns=columns,
                            angles=angles) if learn_from is not None else None)
    again = (timing_trace(repeat, program, machine, fmt=fmt, columns=columns, angles=angles)
             if repeat is not None else None)
    result = compensate_at_timing(servo, program, trace, learn_from=learned, repeat=again,
                                  method=method, tcp=tcp,
                                  into="blocks" if overlay_output is None else "overlay")
    with outputs:
        if overlay_output is None:
            atomic_write(output, result.program.text.encode())
        else:
            from ..toolpath.writers import ProgramInfo, halstreamer_lines

            rows = overlay_offsets(trace, result.commands, result.move_lines)
            # halstreamer_lines writes q in mm and rad: the rows are mm and degrees
            rows[:, 3:] = np.radians(rows[:, 3:])
            info = ProgramInfo(machine=machine.name, method="overlay: compensated minus "
                               "the controller's commands, from the program's first move")
            text = "".join(halstreamer_lines(rows, trace.period, info=info))
            atomic_write(overlay_output, text.encode())
            atomic_write(output, overlay_program(program.read_text(),
                                                 int(result.move_lines[0])).encode())
        if commands_output is not None:
            names = tuple(machine.axis_names)
            write_columns(commands_output, {"t": trace.t - trace.t[0],
                                            **{a: result.commands[:, i]
                                               for i, a in enumerate(names)}})
        if trace_output is not None:
            write_columns(trace_output, _trace_columns(trace, tuple(machine.axis_names)))
    return result
