"""Learning against the virtual machine segment by segment: programs of any length.

Learning within the limits (:func:`~.within_limits.learn_within_limits`) runs every command it
tries on every draw of the machine model over the whole trajectory at once, so its memory
grows with the program times the candidates and the draws. Above
:data:`~.pieces.AT_ONCE_SAMPLES` samples it runs here instead, on segments of about
:data:`~.pieces.PIECE_SAMPLES` kept samples (cut as :func:`~.pieces.plan_pieces` cuts, in the
middle of a stop where the program has one near the planned cut), one after the other, in
memory bounded by the segment and time linear in the program.

Each segment is learned on its kept samples plus a lead-in and a lead-out of
:func:`~.pieces.overlap_samples` (one prediction in the chain: the slowest pole's decay to
1e-9, the closest-point search's widest window, the smoothing of the correction, the spline
fits' end effects; 2.0 s for LinuxCNC's xyzac-trt with `pid-high`):

- The virtual machine starts at rest on its first command with zero controller state. Why a
  lead-in rather than cuts at rests alone: a rest does not settle the machine (static friction
  holds each axis wherever it stopped, the integrator keeps what it held), and long programs
  need not stop at all (LinuxCNC's impeller has no stop of 0.1 s in its first 200 s). In
  motion the machine forgets where it started: started from rest mid-motion at four places of
  the impeller (compensated commands, `pid-high`, realistic machine), its motion differed from
  the whole program's by 2-21 um after 50 ms, 0.03-0.15 um after 0.2 s, 1e-6 um after 0.5 s
  and by round-off (1e-14 mm) from 1 s on, to the end of a 170 s window. That holds for the
  machine file's machine, which reads its axes exactly; a draw with a quantised encoder does
  not forget (where it rests and what its integrator holds carry a change far on: on the
  impeller, lines whose command was the uncompensated one itself differed by up to 7.5 um
  from the uncompensated run 108-295 s after the last command that differed), so a segment's
  judgement of its kept samples on such a draw is close, not exact. The lead-in's
  commands are those already decided (the previous segment's), held there for every command
  learning tries, so the kept samples are judged on the motion the machine will have.
- Only the kept samples are judged (every command's errors elsewhere count as zero), so each
  sample's choice and each block's fallback are taken in one segment only; a source line cut
  by a segment's end is judged in two parts, each nowhere worse than the uncompensated
  command's part (the margins of the part are within the whole line's).
- The previous segment's commands blend into this one's with a C2 weight over the first
  :data:`SEGMENT_BLEND` s of its kept samples, judged with them.
- The lead-out lets the corrections near the kept end see the path after it (the learning
  update is a contour correction: closest points, lead blends and its smoothing reach ahead).
- Only the last segment holds the program's final dwell, so only it tries settled tails.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..machine.servo import Servo
from ..trajectory.limits import check_limits
from ..trajectory.sampled import Trajectory
from .blocks import SUMMARY_KEYS, Fallback
from .pieces import PIECE_SAMPLES, Piece, _slice, overlap_samples, plan_pieces
from .stops import SETTLE_DELAYS, LearningReport
from .within_limits import LimitedCompensation, _predicted, _ramp, learn_commands

#: Width (s) of the C2 blend from the previous segment's commands into a segment's, at the
#: start of its kept samples (within the lead-in's length, so the previous segment's lead-out
#: covers it).
SEGMENT_BLEND = 0.2


def plan_segments(reference: Trajectory, models, segment_samples: int = PIECE_SAMPLES
                  ) -> list[Piece]:
    """The segments of ``reference``: kept samples [keep_start, keep_stop) covering it once,
    each with its lead-in and lead-out (:func:`~.pieces.plan_pieces`)."""
    overlap = overlap_samples(models, reference.ts, 1)
    blend = int(np.ceil(SEGMENT_BLEND / reference.ts))
    return plan_pieces(reference.n_samples, max(overlap, blend),
                       lambda a, b: reference.q[a:b], segment_samples, reference.ts)


def learn_by_segments(servo: Servo, limited: LimitedCompensation, machine_of, passes: int, *,
                      segment_samples: int = PIECE_SAMPLES, progress=None, update: str = "mean",
                      local: bool = True) -> LimitedCompensation:
    """:func:`~.within_limits.learn_within_limits` of ``limited`` segment by segment (see the
    module docstring). ``machine_of(t, start)`` gives the machine model at the times ``t`` of
    a segment whose first sample is the program's ``start`` (e.g.
    ``lambda t, start: ensemble_actual(t, machine, controller, ensemble, start=start)``: the
    draws read the encoder noise of those samples, as the whole program's check does);
    ``segment_samples``: kept samples per segment. ``update``, ``local``: as for
    :func:`~.stops.learn_at_stops`. ``progress(label, summary)`` after each
    command tried, the label prefixed with the segment. ``result.learning`` joins the
    segments' reports (:func:`join_reports`)."""
    models, limits = servo.models, servo.axis_limits
    reference = limited.reference
    n, ts = reference.n_samples, reference.ts
    line = limited.line
    q_linear = limited.result.trajectory.q
    q = np.array(q_linear, dtype=float, copy=True)
    segments = plan_segments(reference, models, segment_samples)
    blend = int(np.ceil(SEGMENT_BLEND / ts))
    reports = []
    for k, piece in enumerate(segments):
        a, b = piece.start, piece.stop
        first, stop = piece.keep_start - a, piece.keep_stop - a
        part = _slice(reference, a, b)
        if first > 0:
            # weight of the learned command: 0 on the lead-in (the commands already decided),
            # a C2 ramp to 1 over the blend
            weight = _ramp((np.arange(b - a) - first) / blend)[:, None]
            decided = q[a:b].copy()

            def project(q_try, weight=weight, decided=decided):
                return decided + weight * (q_try - decided)
        else:
            project = None
        q_start = q[a:b].copy() if project is None else project(q_linear[a:b])
        # the program's final dwell is the last segment's: only it tries settled tails
        settle_delays = SETTLE_DELAYS if piece.keep_stop >= n else ()
        label = f"segment {k + 1}/{len(segments)}: "
        q_kept, report = learn_commands(
            servo, part, q_start, machine_of(part.t, a), passes,
            line=None if line is None else line[a:b],
            progress=None if progress is None else
            (lambda text, summary, label=label: progress(label + text, summary)),
            scored=(first, stop), project=project, update=update, local=local,
            settle_delays=settle_delays, programmed_end=piece.keep_stop >= n)
        q[a:b] = q_kept if project is None else project(q_kept)
        reports.append((report, stop - first, b - a, label))
    report = join_reports(reports, n)
    after = _predicted(servo, reference.with_axes(q), {}, contour=True).contour
    result = replace(limited.result, trajectory=reference.with_axes(q), after=after,
                     learning=report,
                     iterations=0 if report.chosen == "uncompensated"
                     else limited.result.iterations)
    return replace(limited, result=result,
                   check=check_limits(q, ts, limits, t0=float(reference.t[0])))


def join_reports(reports, n_samples: int) -> LearningReport:
    """One :class:`~.stops.LearningReport` of the segments' ``(report, kept, judged, label)``
    (kept and judged samples of each): per draw, the max is the largest segment's and the
    mean the mean over the program (each segment's mean is over its judged samples, zero
    outside the kept ones). ``linear`` joins each segment's worst draw per key (an upper
    bound of the worst draw's mean). ``chosen`` names what each segment kept."""
    def joined(summaries_of):
        out = {}
        for key in SUMMARY_KEYS:
            values = [summaries_of(r)[key] for r, _, _, _ in reports]
            if key.endswith("_max_um") or key.endswith("_max_mrad"):
                out[key] = max(values)
            else:
                out[key] = sum(v * judged for v, (_, _, judged, _) in zip(values, reports)) \
                    / n_samples
        return out

    draws = reports[0][0].draws
    uncompensated = tuple(joined(lambda r, d=d: r.uncompensated_draws[d]) for d in range(draws))
    kept = tuple(joined(lambda r, d=d: r.kept_draws[d]) for d in range(draws))

    def worst(per_draw):
        return {key: max(s[key] for s in per_draw) for key in SUMMARY_KEYS}

    chosen = [r.chosen for r, _, _, _ in reports]
    if all(c == "uncompensated" for c in chosen):
        label = "uncompensated"
    else:
        label = f"by segment ({len(reports)}): " + "; ".join(
            f"{i + 1}: {c}" for i, c in enumerate(chosen))
    fallbacks = [r.fallback for r, _, _, _ in reports if r.fallback is not None]
    fallback = None
    if fallbacks:
        fallback = Fallback(blocks=tuple(b for f in fallbacks for b in f.blocks),
                            rounds=sum(f.rounds for f in fallbacks),
                            everywhere=all(r.fallback is not None and r.fallback.everywhere
                                           for r, _, _, _ in reports))
    candidates = tuple(replace(c, label=text + c.label) for r, _, _, text in reports
                       for c in r.candidates)
    return LearningReport(chosen=label, uncompensated=worst(uncompensated),
                          linear=joined(lambda r: r.linear), kept=worst(kept),
                          candidates=candidates,
                          machine_runs=sum(r.machine_runs for r, _, _, _ in reports),
                          draws=draws, uncompensated_draws=uncompensated, kept_draws=kept,
                          fallback=fallback,
                          fallback_runs=sum(r.fallback_runs for r, _, _, _ in reports))
