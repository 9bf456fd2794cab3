"""Compensation at stops and reversals under friction: learning against a nonlinear machine.

The linear error model of spec section 3 has no friction. On a machine with Stribeck friction
and feed-forward friction compensation from the *commanded* velocity, the compensated command
leads the axis, so near every zero-velocity point (an axis reversal, the final stop) its
velocity changes sign before the axis's does; the feed-forward then pushes with the full static
friction torque the wrong way, and static friction holds the axis wherever it comes to rest.
The largest remaining contour error sits there, often in the final dwell.

This module owns the remedy, measured as the best of the ideas tried (see
``scripts/measure_compensation.py``): model-based iterative learning. The contour correction of
spec section 6 is re-run with the actual motion of a nonlinear machine model in place of the
linear prediction (a callable, in practice the virtual machine with friction, passed in because
compensation comes before simulation in the pipeline), in two sequences: the plain update, and
one whose step along each update is line-searched on the machine. Each iterate is also tried
with its final-dwell tail settled (held exactly at the end position from a delay after the stop
on, so that a slowly creeping command does not switch the friction feed-forward on). Both
sequences may be learned again in variants of the commands (every axis the reference never
moves held at its reference, where the linear passes corrected one), whose iterates compete
with the others. On an ensemble, the best admissible command of them all then takes a
fraction of the update learned from its worst draw alone, which competes too (as it is: it is
not made to fall back locally). Where the commands must keep the axis limits, each update and
settling is smoothed and a command beyond a limit is not kept.

Where static friction holds an axis is decided by nanometres, so a choice taken on one exact
simulation is a coin toss (issue 21: on `paper` / `pid-high` the command kept left 0.48, 0.51,
1.37 or 1.89 um over 30 draws of 1e-9 mm of input noise). The machine model may therefore be an
ensemble of draws of the machine (:func:`precontour.simulation.ensemble_actual`), and every
choice is taken on all of them (:mod:`.blocks`): an update learns from the draws' mean motion,
the line search continues from the step whose worst draw is best, and the command kept is the
one whose worst draw is best among those nowhere worse than the uncompensated command on every
draw (max and mean, tip and orientation), and block by block (beyond the margins and the
uncompensated command's repeatability, :func:`~.blocks.with_repeatability`): where the best ones
hurt in a block, or are worse in whole on a draw because of some blocks, they fall back there
(C2, to another candidate that does not hurt there, to tracking-error pre-compensation, or to
the planned command) and are kept only where they still improve on the uncompensated command,
and the report says where and why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..defaults import DEFAULT_LEARNING_PASSES
from ..errors import PrecontourError
from ..files import check_signals
from ..parallel import map_ordered
from .blocks import (PROGRAM_MARGIN, SUMMARY_KEYS, TIE, Fallback, best,
                     block_starts, fall_back, improves, judge, not_finite, repaired_score,
                     score, splice_errors, whole_ok, with_repeatability, worse_blocks)

# DEFAULT_LEARNING_PASSES (CLI ``compensate --learn``) is defined in precontour.defaults.
#: Delays after the final stop (s) from which an iterate's tail is settled, tried per iterate:
#: every 10 ms from 0 to 100 ms. Why a grid (issue 13 section 1, "a settling criterion for the
#: final dwell"): static friction holds each axis wherever it comes to rest, and while the
#: learned command still moves in the dwell the feed-forward keeps switching the full static
#: friction torque; settling the tail stops both, and *when* decides which axes are already at
#: rest and on which side of the end point. That outcome changes abruptly with the delay (on
#: the test path `fan25` with `pid-high`, pass 2 settled at 30 / 60 / 80 ms removes 65 / 82 /
#: 88 % of the max tip error), so the delay is searched on the machine model itself, at one
#: machine run and one contour evaluation per delay. With the former three delays (0, 30,
#: 60 ms) `fan25` / `pid-high` ended at 82.3 %, with this grid at 87.7 % (plain sequence; a
#: 5 ms grid changed no built-in or test path with the line search below, at twice the cost).
SETTLE_DELAYS: tuple[float, ...] = tuple(0.01 * k for k in range(11))
#: Steps along each learning update tried by the line-searched sequence, as fractions of the
#: full update; the best on the machine model is the next iterate. Why (issue 13 section 1,
#: "iterate the compensation against the nonlinear virtual machine"): the update re-applies
#: the whole measured contour error, as if the machine answered a command change linearly;
#: near a reversal under friction it does not, the full step can overshoot, and the iterates
#: oscillate (on a fan whose largest learned error sits at interior reversals,
#: ``_fan_reversals`` in ``tests/compensation/test_stops.py``, `pid-high`, the plain
#: sequence's maximum jumps between the reversals near 0.98 s and 1.46 s from pass to pass and
#: ends at 79.1 % of the max tip error removed); a half step damps that (91.1 %). No fixed step
#: suits every path (with step 1/2 alone `cone` / `pid-high` ends at 85.7 % instead of
#: 87.2 %), so the plain sequence is kept and this one added; `fan25` / `pid-high` 87.7 ->
#: 92.9 % (measured on the realistic machine, 4 passes; 91.9 % once the faster closest-point
#: search changed the round-off).
LINE_SEARCH_STEPS: tuple[float, ...] = (0.5, 1.0)
#: Standard deviation (s) of the Gaussian filter that smooths each learning update and each
#: settling where the commands must keep the axis limits (``precontour run --learn``). Why: the
#: update carries the machine's stick-slip response sample by sample, and a settled tail steps;
#: unsmoothed, the learned commands' peak jerk was 1.6-184 times the jerk limit on the built-in
#: and test paths (the linear pass's 0.25-161 times). Smoothed over 3 ms (the Q-filter of
#: iterative learning control) the peak jerk stayed within 5 % of the limit from the linear
#: pass's on the seven paths with `pid-high` (below the limit wherever the linear pass was),
#: and learning still removed 89.0 % of the max tip error on `fan25` and 98.7 % on `paper`
#: (linear pass 72.6 and 88.2 %).
LIMITED_SMOOTHING = 0.003
#: Steps (fractions of the update) along the update learned from the worst draw alone, tried
#: from the best admissible command of both sequences once they are done. Why: an update
#: learns from the draws' mean motion, so the sequences converge on the mean machine, and what
#: the worst draw has that the mean machine has not stays (on `cone` / `pid-low`, draw 3's A
#: friction 0.7 / 1.7 % below the feed-forward's leaves about 45 urad at A's reversals
#: whatever the pass; a quarter of one update from draw 3 removes 95.3 % of the mean tip error
#: on every draw, half of one 94.1 %). It is kept only where its worst draw wins, which may
#: cost the machine file's machine: with `compensate --learn`, `fan` / `pid-high` 2.83 -> 4.09
#: um there (flank 2.49 -> 1.28 um). Measured: docs/learning.md.
WORST_DRAW_STEPS: tuple[float, ...] = (0.25,)
#: Candidates that :func:`learn_at_stops` makes fall back locally, in each of two groups: the
#: admissible ones that hurt somewhere block by block (the best by their worst draw), then
#: those worse in whole on some draw (the best by their estimated mended worst draw,
#: :func:`~.blocks.repaired_score`); each at up to :data:`~.blocks.FALLBACK_ROUNDS`
#: judgements on the machine model.
REPAIRED_CANDIDATES = 3
#: Other candidates (the best by their worst draw) a block may fall back to first, where one
#: is nowhere worse there (:func:`~.blocks.fall_back`; choosing costs no machine run).
ALTERNATIVES = 20
#: What each learning update learns from where the machine model is an ensemble
#: (:mod:`.blocks`): ``"mean"``, the mean actual motion over the draws, or ``"nominal"``,
#: draw 0's alone.
UPDATES: tuple[str, ...] = ("mean", "nominal")

#: A nonlinear machine model: axis commands (N, 5) in, actual axis positions out, (N, 5) for
#: one machine or (D, N, 5) for an ensemble of D draws of it
#: (:func:`precontour.simulation.ensemble_actual`).
MachineActual = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class LearningCandidate:
    """One command tried on the machine model: its label, its contour errors on the worst
    draw per key (``ContourErrors.summary``: tip max/mean in um, orientation max/mean in
    mrad), whether it was admissible (nowhere worse in whole on every draw, within the limits
    asked for, finite), whether it was also nowhere worse block by block
    (:func:`~.blocks.nowhere_worse`), and whether it may be repaired by a local fallback
    (``repairable``: finite and within the limits asked for, whether accepted or not)."""

    label: str
    summary: dict
    accepted: bool
    blocks_ok: bool = True
    median: dict | None = None
    repairable: bool = True


@dataclass(frozen=True)
class LearningReport:
    """What learning against the machine model tried and kept.

    Attributes
    ----------
    chosen : str
        Label of the command kept: ``"uncompensated"``, ``"linear"`` (the linear passes'
        result), ``"pass n"`` (plain update) or ``"line-searched pass n (step s)"``, optionally
        with ``", settled d ms"``, then the name of the variant it was learned in (e.g.
        ``", resting axes held"``), then either ``", then draw d's update (step s)"`` where
        it took a step along the update learned from its worst draw
        (:data:`WORST_DRAW_STEPS`), or ``", fell back in n block(s)"`` where it gave way
        locally (:attr:`fallback`), optionally with ``", within 1 % of the uncompensated
        max"`` (the second chance, :data:`~.blocks.PROGRAM_MARGIN`).
    uncompensated, linear, kept : dict
        Contour errors on the machine model (``ContourErrors.summary``) of the reference
        command, of the linear compensation, and of the command kept: per key the worst over
        the draws.
    candidates : tuple of LearningCandidate
        Every command tried, in order.
    machine_runs : int
        Machine runs (one per draw of each call of the machine model).
    draws : int
        Draws of the machine model (1: a single machine).
    uncompensated_draws, kept_draws : tuple of dict
        Per draw, the contour errors of the reference command and of the command kept.
    fallback : Fallback or None
        Where the command kept gave way block by block (:func:`~.blocks.fall_back`); None
        when it did not.
    fallback_runs : int
        Of :attr:`machine_runs`, those spent judging local fallbacks.
    """

    chosen: str
    uncompensated: dict
    linear: dict
    kept: dict
    candidates: tuple
    machine_runs: int
    draws: int = 1
    uncompensated_draws: tuple = ()
    kept_draws: tuple = ()
    fallback: Fallback | None = None
    fallback_runs: int = 0

    @property
    def kept_median(self) -> dict:
        """Per key, the median over the draws of the command kept."""
        return {key: float(np.median([s[key] for s in self.kept_draws]))
                for key in SUMMARY_KEYS}


def final_rest_index(q: np.ndarray) -> int | None:
    """First sample of the final rest: ``q[k:]`` all equal ``q[-1]``; None when the command
    still moves at its last sample (no dwell)."""
    moving = np.flatnonzero(np.any(q[1:] != q[:-1], axis=1))
    if moving.size == 0:
        return 0
    first = int(moving[-1]) + 1
    return None if first >= q.shape[0] - 1 else first


def settle_final_dwell(q: np.ndarray, q_reference: np.ndarray, start: int) -> np.ndarray:
    """``q`` with samples ``start`` on held exactly at the reference's final position."""
    settled = np.array(q, dtype=float, copy=True)
    settled[start:] = q_reference[-1]
    return settled


@dataclass(frozen=True)
class LearningSettings:
    """How :class:`Learner` learns (see :func:`learn_at_stops` for each field): the passes
    per sequence, the settling delays, the line search's steps, the smoothing of each update,
    what an update learns from on an ensemble, whether the command kept must also be nowhere
    worse block by block, and the steps along the worst draw's own update."""

    passes: int = DEFAULT_LEARNING_PASSES
    settle_delays: tuple[float, ...] = SETTLE_DELAYS
    line_search_steps: tuple[float, ...] = LINE_SEARCH_STEPS
    smoothing: float = 0.0
    update: str = "mean"
    local: bool = True
    worst_draw_steps: tuple[float, ...] = WORST_DRAW_STEPS

    def __post_init__(self):
        if self.passes < 0:
            raise ValueError(f"learning passes must be >= 0, got {self.passes}")
        if self.update not in UPDATES:
            raise ValueError(f"unknown learning update {self.update!r}; choose one of "
                             f"{', '.join(UPDATES)}")


@dataclass(frozen=True)
class LearningProblem:
    """What :class:`Learner` learns against (see :func:`learn_at_stops` for each field): the
    reference commands and their sample period, the machine model (and its draws run again),
    the contour errors of a motion (and of a tail of one), the contour step, and the blocks'
    source lines and first sample time."""

    q_reference: np.ndarray
    ts: float
    machine_actual: MachineActual
    errors_of: Callable
    contour_step: Callable
    line: np.ndarray | None = None
    t0: float = 0.0
    tail_errors_of: Callable | None = None
    repeat_actual: MachineActual | None = None


class Learner:
    """One run of learning at stops (:func:`learn_at_stops`): the commands tried, their
    judgements on every draw of the machine model, and the choice of the command kept.

    Its parts, in the order :meth:`learn` takes them: :meth:`consider` runs a command on the
    machine model and records its judgement; :meth:`learn_sequences` learns the plain and the
    line-searched sequences of every variant; :meth:`refine_on_worst_draw` tries the worst
    draw's own update; :meth:`choose` takes the command kept, falling back locally where it
    hurts (:meth:`repair`). How a candidate is picked is :meth:`choose` (and
    :func:`~.blocks.best`, the order of judgements)."""

    def __init__(self, problem: LearningProblem, settings: LearningSettings = LearningSettings(),
                 *, admissible: Callable[[np.ndarray], bool] | None = None, progress=None,
                 fallbacks: Sequence[tuple[str, np.ndarray]] = (),
                 variants: Sequence[tuple[str, Callable[[np.ndarray], np.ndarray]]] = ()):
        self.problem, self.settings = problem, settings
        self.progress, self.fallbacks, self.variants = progress, fallbacks, variants
        self.admissible = admissible
        q_reference, ts = problem.q_reference, problem.ts
        n = q_reference.shape[0]
        self.starts = block_starts(n, ts, problem.line)
        self.runs = 0
        self.draws = 0
        rest = final_rest_index(q_reference)
        self.settle_starts = []
        if rest is not None:
            for delay in settings.settle_delays:
                start = rest + int(round(delay / ts))
                if start < n - 1:
                    self.settle_starts.append((delay, start))
        self.sigma = settings.smoothing / ts
        self.entries = []    # (candidate, q, judgement)
        self.suffix = ""     # the name of the variant being learned, if any
        self.project = None  # the projection of the variant being learned, if any
        # By the id of a command tried (entries keep every one alive, so no id is reused): the
        # projection of the variant it was learned in, and where its tail is settled from
        self.projections = {}
        self.settled = {}
        self.reference = None

    # ------------------------------------------------------------------ the machine model
    def run(self, q, model=None):
        """The machine model's actual motions of ``q``, shape (D, N, 5), or None
        when ``q`` or a motion is not finite (a diverging update is simply not kept)."""
        machine_actual = self.problem.machine_actual
        model = machine_actual if model is None else model
        if not np.all(np.isfinite(q)):
            return None
        motion = np.asarray(model(q), dtype=float)
        if motion.ndim == 2:
            motion = motion[None]
        self.runs += motion.shape[0]
        if model is machine_actual:
            self.draws = motion.shape[0]
        return motion if np.all(np.isfinite(motion)) else None

    def learned_from(self, motion):
        return motion.mean(axis=0) if self.settings.update == "mean" else motion[0]

    def actual(self, q):
        """The contour step's machine: one motion per command, as ``update`` says."""
        motion = self.run(q)
        return np.full(q.shape, np.nan) if motion is None else self.learned_from(motion)

    def judge_command(self, q, like=None):
        """The judgement of ``q``, its motions and their contour errors; ``like``: the motions
        and errors of a command that ``q`` equals up to some sample (a settled tail), whose
        errors are reused up to where the motions part (the machine is causal)."""
        errors_of, tail_errors_of = self.problem.errors_of, self.problem.tail_errors_of
        motion = self.run(q)
        if motion is None:
            return not_finite(max(self.draws, 1), self.starts.size), None, None
        if like is None or like[0] is None or tail_errors_of is None \
                or like[0].shape != motion.shape:
            # the draws' contour errors side by side (threads: the closest-point search
            # releases the GIL), as their motions were run
            errors = list(map_ordered(errors_of, motion))
        else:
            parted = np.flatnonzero(np.any(motion != like[0], axis=(0, 2)))
            if parted.size == 0:
                errors = list(like[1])
            else:
                first = int(parted[0])
                errors = list(map_ordered(
                    lambda pair: splice_errors(pair[0], tail_errors_of(pair[1][first:], first),
                                               first), zip(like[1], motion)))
        return judge(errors, self.starts), motion, errors

    def judged_safely(self, q, like=None):
        """:meth:`judge_command`, a command that diverged judged not finite: one that is not
        finite, whose motion is not, or that the machine model or the contour errors refuse
        (e.g. coordinates out of range)."""
        check_signals()  # between machine runs: where a SIGTERM or Ctrl-C stops learning
        try:
            with np.errstate(all="ignore"):
                return self.judge_command(q, like)
        except PrecontourError:
            return not_finite(max(self.draws, 1), self.starts.size), None, None

    def judge_reference(self):
        """The uncompensated command's judgement, with its repeatability (the draws run
        again) where the command kept must be nowhere worse block by block."""
        q_reference, repeat_actual = self.problem.q_reference, self.problem.repeat_actual
        reference, _, _ = self.judge_command(q_reference)
        if not reference.finite:
            raise ValueError("the machine model's motion of the uncompensated command is not "
                             "finite")
        again = (None if repeat_actual is None or not self.settings.local
                 else self.run(q_reference, repeat_actual))
        if again is not None:
            reference = with_repeatability(
                reference, judge((self.problem.errors_of(m) for m in again), self.starts))
        self.reference = reference
        self.entries.append((LearningCandidate("uncompensated", reference.worst, True, True,
                                               reference.median), q_reference, reference))

    # ------------------------------------------------------------------ commands tried
    def consider(self, label, q, like=None):
        """Judge and record ``q``; returns what an update learns from (None when it
        diverged: such a candidate is never kept) and its motions and errors (for
        :meth:`consider_settled`)."""
        judged, motion, errors = self.judged_safely(q, like)
        label += self.suffix
        if not judged.finite:
            label += " (diverged)"
        repairable = judged.finite and (self.admissible is None or self.admissible(q))
        ok = repairable and whole_ok(judged, self.reference)
        blocks_ok = ok and not worse_blocks(judged, self.reference).any()
        self.entries.append((LearningCandidate(label, judged.worst, ok, blocks_ok,
                                               judged.median, repairable), q, judged))
        if self.project is not None:
            self.projections[id(q)] = self.project
        if self.progress is not None:
            self.progress(label, judged.worst)
        return (None if motion is None else self.learned_from(motion)), (motion, errors)

    def towards(self, q, q_new):
        """``q_new``, or with smoothing ``q`` plus the smoothed change to ``q_new``."""
        if self.sigma <= 0 or not np.all(np.isfinite(q_new)):
            return q_new
        return q + gaussian_filter1d(q_new - q, self.sigma, axis=0, mode="nearest")

    def alone(self, draw):
        """The machine model's draw ``draw`` alone as the contour step's machine (one motion
        per command, not finite where it diverged), on its one-draw model where it has one."""
        one = getattr(self.problem.machine_actual, "draw", None)

        def one_draw(q_cmd):
            return one(q_cmd, draw)

        def motion(q):
            motions = self.run(q) if one is None else self.run(q, one_draw)
            if motions is None:
                return np.full(q.shape, np.nan)
            return motions[draw] if one is None else motions[0]
        return motion

    def step_from(self, q_cmd, q_act, model=None):
        """The next iterate, or None when the update diverged; ``model``: the machine the
        update learns from where not :meth:`actual` (the motion of ``q_cmd`` then run here)."""
        contour_step = self.problem.contour_step
        try:
            with np.errstate(all="ignore"):
                if model is None:
                    q_new = self.towards(q_cmd, contour_step(q_cmd, q_act, self.actual))
                else:
                    q_new = self.towards(q_cmd, contour_step(q_cmd, model(q_cmd), model))
                if self.project is not None:
                    q_new = self.project(q_new)
        except PrecontourError:
            return None
        return q_new if np.all(np.isfinite(q_new)) else None

    def settle(self, q, start):
        """``q`` with its tail settled from sample ``start`` on (smoothed as updates are)."""
        q_settled = self.towards(q, settle_final_dwell(q, self.problem.q_reference, start))
        self.settled[id(q_settled)] = start
        return q_settled

    def consider_settled(self, label, q, like):
        for delay, start in self.settle_starts:
            self.consider(f"{label}, settled {1e3 * delay:.0f} ms", self.settle(q, start), like)

    # ------------------------------------------------------------------ the sequences
    def learn_sequences(self, q_linear):
        """Both sequences from ``q_linear`` and from each variant's projection of it.

        Each variant learns both sequences again from its projection of q_linear. One that
        leaves q_linear as it is starts from the linear command's judgement (not run again),
        and adds nothing where it leaves the first plain pass as it is too: a resting axis
        that the linear passes held may still be moved by the updates, which learn from every
        axis's actual motion (on `circle` / `pid-high` pass 1 moved X, which the reference
        never moves, by up to 1.4 um, and X slipped 44 um on one draw)."""
        main = None     # the main sequence's linear motion and first plain iterate
        for name, projection in (("", None), *self.variants):
            q_first = q_linear if projection is None else projection(q_linear)
            if projection is not None and q_first is q_linear and (
                    main[2] is None or projection(main[2]) is main[2]):
                continue
            self.suffix, self.project = (f", {name}" if name else ""), projection
            if projection is not None and q_first is q_linear:
                q_act_linear, linear_state = main[0], main[1]
            else:
                q_act_linear, linear_state = self.consider("linear", q_first)
                self.consider_settled("linear", q_first, linear_state)
            plain = self.plain_sequence(q_first, q_act_linear)
            if projection is None:
                main = (q_act_linear, linear_state, plain[0][0] if plain else None)
            if self.settings.line_search_steps:
                self.line_searched_sequence(q_first, q_act_linear, plain)

    def plain_sequence(self, q_first, q_act_linear):
        """The plain sequence: each pass applies the whole update. A sequence that diverges
        (an iterate not finite, or refused by the machine model) ends there: what it tried
        before stays a candidate, the diverged iterate is never kept. Per pass: the plain
        iterate, its entry and what an update learns from."""
        q_cmd, q_act = q_first, q_act_linear
        plain = []
        for k in range(1, self.settings.passes + 1):
            q_cmd = None if q_act is None else self.step_from(q_cmd, q_act)
            if q_cmd is None:
                break
            q_act, state = self.consider(f"pass {k}", q_cmd)
            if q_act is None:
                break
            plain.append((q_cmd, self.entries[-1], q_act))
            self.consider_settled(f"pass {k}", q_cmd, state)
        return plain

    def line_searched_sequence(self, q_first, q_act_linear, plain):
        """The line-searched sequence: each pass continues from the best step along the
        update, best on its worst draw. While it has taken the whole update at every pass,
        its whole step is the plain iterate itself: that iterate's judgement is taken, not
        run again, and its settled tails were tried with it (on a long program, one update
        and one judgement of every draw per segment saved)."""
        q_cmd, q_act = q_first, q_act_linear
        on_plain = True
        for k in range(1, self.settings.passes + 1):
            same = on_plain and k <= len(plain)
            if same:
                q_full = plain[k - 1][0]
            else:
                q_full = None if q_act is None else self.step_from(q_cmd, q_act)
            if q_full is None:
                break
            tried = []
            for step in self.settings.line_search_steps:
                label = f"line-searched pass {k} (step {step:g})"
                if same and step == 1.0:
                    _, (candidate, _, judged), q_act_try = plain[k - 1]
                    self.entries.append((replace(candidate, label=label + self.suffix),
                                         q_full, judged))
                    if self.progress is not None:
                        self.progress(label + self.suffix, judged.worst)
                    tried.append((judged, label, q_full, q_act_try, None))
                    continue
                with np.errstate(all="ignore"):
                    q_try = q_full if step == 1.0 else q_cmd + step * (q_full - q_cmd)
                q_act_try, state = self.consider(label, q_try)
                if q_act_try is not None:
                    tried.append((self.entries[-1][2], label, q_try, q_act_try, state))
            if not tried:
                break
            _, label, q_cmd, q_act, state = tried[best([entry[0] for entry in tried])]
            on_plain = same and q_cmd is q_full
            if not on_plain:
                self.consider_settled(label, q_cmd, state)

    def refine_on_worst_draw(self):
        """The worst draw's own update: from the best admissible command so far, a fraction
        of the update learned from the motion of its worst draw alone, per step of
        ``worst_draw_steps``. The ids of the commands it tries: kept as they are or not at all
        (neither mended nor taken in a block by another's fallback)."""
        refinements = set()
        settings = self.settings
        if not (self.draws > 1 and settings.passes > 0 and settings.worst_draw_steps):
            return refinements
        so_far = [entry for entry in self.entries if entry[0].accepted]
        origin, q_origin, judged_origin = so_far[best([entry[2] for entry in so_far])]
        if q_origin is self.problem.q_reference:
            return refinements
        worst_draw = int(np.argmax([score(s) for s in judged_origin.summaries]))
        # learned as its own variant was, its tail settled where its own was
        self.suffix, self.project = "", self.projections.get(id(q_origin))
        settled_from = self.settled.get(id(q_origin))
        q_update = self.step_from(q_origin, None, self.alone(worst_draw))
        for step in ([] if q_update is None else settings.worst_draw_steps):
            with np.errstate(all="ignore"):
                # (both held where the variant holds: so is their combination)
                q_try = q_origin + step * (q_update - q_origin)
            if settled_from is not None:
                q_try = self.settle(q_try, settled_from)
            self.consider(f"{origin.label}, then draw {worst_draw}'s update (step {step:g})",
                          q_try)
            refinements.add(id(q_try))
        return refinements

    # ------------------------------------------------------------------ the choice
    def repair(self, entry, alternatives=(), program_margin=0.0):
        """``entry`` fallen back where it hurts (:func:`~.blocks.fall_back`): its entry and
        the report, or None where only the planned command everywhere would do, or where it
        no longer improves on the uncompensated command (:func:`~.blocks.improves`)."""
        problem = self.problem
        candidate, q_try, judged_try = entry
        q_fixed, judged, report_try = fall_back(
            q_try, judged_try, problem.q_reference, self.reference,
            lambda q: self.judged_safely(q)[0], self.starts, problem.ts,
            alternatives=alternatives, fallbacks=self.fallbacks, admissible=self.admissible,
            line=problem.line, t0=problem.t0, program_margin=program_margin)
        if report_try.everywhere or not improves(judged, self.reference):
            return None
        label = f"{candidate.label}, fell back in {len(report_try.blocks)} block(s)"
        return ((LearningCandidate(label, judged.worst, True, True, judged.median),
                 q_fixed, judged), report_try)

    def choose(self, refinements):
        """The entry kept, the fallback it took (or None) and the machine runs the fallbacks
        cost. Besides the admissible commands, every finite command within the limits that is
        worse in whole on some draw may be repaired: that is worse there in some block, which
        the fallback mends like any other (on LinuxCNC's boat, a segment whose linear command
        was worse on one draw's max kept the uncompensated command with no fallback tried).
        They are ranked by their estimated mended worst draw (blocks.repaired_score) and
        tried after the admissible ones."""
        q_reference, reference, entries = self.problem.q_reference, self.reference, self.entries
        accepted = [entry for entry in entries if entry[0].accepted]
        ranks = np.array([entry[2].score for entry in accepted])
        kept = accepted[best([entry[2] for entry in accepted])]
        unadmitted = [entry for entry in entries if entry[0].repairable
                      and not entry[0].accepted and id(entry[1]) not in refinements]
        if not (self.settings.local
                and (not kept[0].blocks_ok or (kept[1] is q_reference and unadmitted))):
            return kept, None, 0
        # The best candidates that hurt somewhere fall back there; the best of them is kept
        # if it beats the best candidate that needed no fallback. Several are tried because
        # where a fallback lands (a stop, the final dwell) decides what it costs.
        safe_rank = min(r for r, entry in zip(ranks, accepted) if entry[0].blocks_ok)
        order = [accepted[i] for i in np.argsort(ranks, kind="stable")
                 if ranks[i] <= safe_rank * (1.0 + TIE) and not accepted[i][0].blocks_ok
                 and id(accepted[i][1]) not in refinements][:REPAIRED_CANDIDATES]
        estimates = np.array([repaired_score(entry[2], reference) for entry in unadmitted])
        order += [unadmitted[i] for i in np.argsort(estimates, kind="stable")
                  if estimates[i] <= safe_rank * (1.0 + TIE)][:REPAIRED_CANDIDATES]
        # a command tried under two labels (a line-searched whole step on the plain track) is
        # repaired once
        unique = {}
        for entry in order:
            unique.setdefault(id(entry[1]), entry)
        order = list(unique.values())
        ranked = [accepted[i] for i in np.argsort(ranks, kind="stable")
                  if accepted[i][1] is not q_reference and id(accepted[i][1]) not in refinements]
        repaired = []
        runs_before = self.runs
        for entry in order:
            alternatives = [(c.label, q_alt, j) for c, q_alt, j in ranked
                            if q_alt is not entry[1]][:ALTERNATIVES]
            fixed = self.repair(entry, alternatives)
            if fixed is not None:
                repaired.append(fixed)
        pool = [entry for entry in accepted if entry[0].blocks_ok] + [e for e, _ in repaired]
        kept = pool[best([entry[2] for entry in pool])]
        fallback = next((f for e, f in repaired if e is kept), None)
        if kept[1] is q_reference:
            # Nothing is nowhere worse within the block margins: before giving the
            # uncompensated command back, the second chance of blocks.PROGRAM_MARGIN (a
            # fallback's blend on a curved path can itself leave the neighbours a few % worse)
            loose = [entry for entry in accepted if entry[1] is not q_reference
                     and not worse_blocks(entry[2], reference, PROGRAM_MARGIN).any()]
            for entry in ([] if loose else order):
                fixed = self.repair(entry, program_margin=PROGRAM_MARGIN)
                if fixed is not None:
                    loose.append(fixed[0])
                    repaired.append(fixed)
            if loose:
                kept = loose[best([entry[2] for entry in loose])]
                kept = (replace(kept[0], label=f"{kept[0].label}, within "
                                               f"{100 * PROGRAM_MARGIN:g} % of the "
                                               "uncompensated max"),) + kept[1:]
                fallback = next((f for e, f in repaired if e[1] is kept[1]), None)
        return kept, fallback, self.runs - runs_before

    def learn(self, q_linear):
        """Learn from the linear compensation ``q_linear``: the command kept and the report
        (see :func:`learn_at_stops`)."""
        self.judge_reference()
        self.learn_sequences(q_linear)
        refinements = self.refine_on_worst_draw()
        linear = next(c for c, _, _ in self.entries
                      if c.label in ("linear", "linear (diverged)"))
        (chosen, q_kept, judged), fallback, fallback_runs = self.choose(refinements)
        reference = self.reference
        report = LearningReport(chosen=chosen.label, uncompensated=reference.worst,
                                linear=linear.summary, kept=chosen.summary,
                                candidates=tuple(c for c, _, _ in self.entries),
                                machine_runs=self.runs, draws=reference.draws,
                                uncompensated_draws=reference.summaries,
                                kept_draws=judged.summaries, fallback=fallback,
                                fallback_runs=fallback_runs)
        return q_kept, report


def learn_at_stops(q_reference: np.ndarray, q_linear: np.ndarray, ts: float,
                   machine_actual: MachineActual, errors_of, contour_step, *,
                   passes: int = DEFAULT_LEARNING_PASSES,
                   settle_delays: tuple[float, ...] = SETTLE_DELAYS,
                   line_search_steps: tuple[float, ...] = LINE_SEARCH_STEPS,
                   smoothing: float = 0.0, admissible: Callable[[np.ndarray], bool] | None = None,
                   progress=None, line: np.ndarray | None = None,
                   fallbacks: Sequence[tuple[str, np.ndarray]] = (), update: str = "mean",
                   local: bool = True, t0: float = 0.0,
                   tail_errors_of=None, repeat_actual: MachineActual | None = None,
                   variants: Sequence[tuple[str, Callable[[np.ndarray], np.ndarray]]] = (),
                   worst_draw_steps: tuple[float, ...] = WORST_DRAW_STEPS
                   ) -> tuple[np.ndarray, LearningReport]:
    """Improve the linear compensation ``q_linear`` against a nonlinear machine model.

    Every decision (which step of a line search to continue from, which command to keep) is
    taken on all the model's draws (:mod:`.blocks`): a command is admissible only if, on
    every draw, its max and mean errors (tip and orientation) do not exceed the uncompensated
    command's there, and the command kept is the admissible one whose worst draw is best.
    With ``local``, the command kept is also nowhere worse block by block: where the best
    admissible command is not, it falls back locally (:func:`~.blocks.fall_back`), and so do
    the best commands worse in whole on some draw (finite and within the limits); a mended
    command is kept if it stays better than the best candidate that needed no fallback and
    improves on the uncompensated command by more than :data:`~.blocks.TIE`
    (:func:`~.blocks.improves`). Each block's margin is at least the uncompensated command's
    repeatability there where ``repeat_actual`` is given.

    Parameters
    ----------
    q_reference, q_linear : ndarray, shape (N, 5)
        The reference commands and their linear compensation.
    ts : float
        Sample period, s.
    machine_actual : callable
        The machine model, commands (N, 5) -> actual axis positions (N, 5), or (D, N, 5) for
        an ensemble of D draws; ``machine_actual.draw(q, d)``, where given, draw ``d``'s
        alone (N, 5) (:func:`~precontour.simulation.ensemble_actual`).
    errors_of : callable
        Actual axis positions (N, 5) -> ``ContourErrors`` against the reference.
    contour_step : callable
        ``contour_step(q_cmd, q_act, actual)`` -> corrected commands: one contour correction
        (spec section 6) of ``q_cmd`` whose actual motion is ``q_act``, ``actual`` giving the
        actual motion of any other command (both as ``update`` says for an ensemble).
    passes : int
        Learning passes per sequence (a plain pass costs two calls of the machine model plus
        one per settling delay, a line-searched pass one more per step size tried beyond the
        first).
    settle_delays : tuple of float
        Delays after the final stop (s) from which each iterate's tail is settled; none when
        the reference has no final dwell.
    line_search_steps : tuple of float
        Steps along the update (fractions of it) tried by the line-searched sequence; empty:
        the plain sequence alone.
    smoothing : float
        Standard deviation (s) of a Gaussian filter applied to each learning update and to
        each settling (0: none); see :data:`LIMITED_SMOOTHING`.
    admissible : callable, optional
        ``admissible(q) -> bool``: commands it refuses (e.g. beyond the axis limits) are not
        kept; the uncompensated command is taken as admissible.
    progress : callable, optional
        ``progress(label, summary)`` after each command tried (the worst draw per key).
    line : ndarray of shape (N,), optional
        Source line of each sample: the blocks judged (:func:`~.blocks.block_starts`; without
        it, windows of :data:`~.blocks.BLOCK_WINDOW`).
    fallbacks : sequence of (str, ndarray)
        Named commands to fall back to locally before the planned one, in order (e.g.
        tracking-error pre-compensation).
    update : {"mean", "nominal"}
        What an update learns from when the model is an ensemble (:data:`UPDATES`).
    local : bool
        Whether the command kept must also be nowhere worse block by block.
    t0 : float
        Time of the first sample (for the fallback's report).
    tail_errors_of : callable, optional
        ``tail_errors_of(q_act_tail, first)``: the contour errors of the actual positions of
        samples ``first`` on (identical to those samples of ``errors_of`` of the whole). With
        it, a settled tail's errors are computed only from where its motion parts from its
        iterate's.
    repeat_actual : callable, optional
        The machine model's draws run again (their encoder noise re-drawn; what
        :func:`~precontour.simulation.ensemble_actual` gives as ``.repeat``): the uncompensated
        command is run on it once, and each block's margin is at least how much its errors
        changed (:func:`~.blocks.with_repeatability`).
    variants : sequence of (str, callable)
        Named projections of commands (e.g. every resting axis held at its reference,
        :func:`~.idle_axes.hold_resting_axes`): for each, both sequences are learned again from
        the projected ``q_linear``, every iterate projected, their labels ending with the
        name; every candidate of every variant competes for being kept. A projection that
        leaves ``q_linear`` and the first plain pass as they are adds nothing.
    worst_draw_steps : tuple of float
        Steps along the update learned from the worst draw alone, tried from the best
        admissible command once both sequences of every variant are done (an ensemble only;
        empty: none), :data:`WORST_DRAW_STEPS`. Such a command is kept as it is or not at all:
        it is neither made to fall back locally (mending it would spend a fallback's
        judgements on a command that only refines one the fallback already tries) nor
        another's fallback in a block.

    Returns
    -------
    q : ndarray, shape (N, 5)
        The command kept.
    report : LearningReport
    """
    settings = LearningSettings(passes=passes, settle_delays=tuple(settle_delays),
                                line_search_steps=tuple(line_search_steps), smoothing=smoothing,
                                update=update, local=local,
                                worst_draw_steps=tuple(worst_draw_steps))
    problem = LearningProblem(q_reference, ts, machine_actual, errors_of, contour_step,
                              line=line, t0=t0, tail_errors_of=tail_errors_of,
                              repeat_actual=repeat_actual)
    learner = Learner(problem, settings, admissible=admissible, progress=progress,
                      fallbacks=fallbacks, variants=variants)
    return learner.learn(q_linear)
