"""The checks of ``run`` on the realistic virtual machine: the uncompensated and the
compensated commands on the machine file's machine (:func:`check_on_virtual_machine`), then on
the draws of a machine ensemble with the uncompensated commands run twice for their
repeatability (:func:`check_on_draws`, :class:`DrawCheck`: what is worse, line by line and in
whole, and its table)."""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Sequence

import numpy as np

from ..compensation.blocks import Judgement
from ..compensation.pieces import contour_errors_program
from ..files import check_signals
from ..machine.machine_file import Machine, load_machine
from ..parallel import map_ordered
from ..prediction.contour import ContourErrors
from ..simulation.ensemble import MachineEnsemble
from ..simulation.virtual_machine import realistic_actual
from ..trajectory.sampled import Trajectory


#: Samples from which the two virtual-machine runs go to two processes when ``workers`` is
#: None. The compiled virtual machine already runs the five axes on two threads, so on this
#: 2-core machine two processes did not pay: on LinuxCNC's impeller (1.5 * 10^6 samples after
#: slowing) the two runs took 12.0 s in two processes and 9.9 s in one. Only far longer
#: programs, on machines with more cores, may gain.
PARALLEL_MIN_SAMPLES = 20_000_000


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
        from ..compensation.blocks import worse_blocks

        return np.flatnonzero(worse_blocks(self.after, self.before))

    def worse_blocks_without_repeatability(self) -> np.ndarray:
        """:meth:`worse_blocks` by the block margins alone."""
        from ..compensation.blocks import worse_blocks

        return np.flatnonzero(worse_blocks(self.after, self.before.without_repeatability()))

    def self_worse_blocks(self) -> np.ndarray:
        """Indices of the blocks where the uncompensated commands run again are worse than
        themselves by the block margins alone: how many blocks the comparison counts that no
        command decides (empty without a rerun)."""
        from ..compensation.blocks import worse_blocks

        if self.again is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(worse_blocks(self.again, self.before.without_repeatability()))

    def worse_in_whole(self) -> tuple[str, ...]:
        """The quantities (``tip max``, ``orientation max``) whose worst draw is above the
        uncompensated commands' worst draw, over both their runs where they ran twice, by more
        than the block margins (or not finite): the compensated program is worse where it is
        worst, and not by the machine's scatter from run to run."""
        from ..compensation.blocks import ORIENTATION_MARGIN, TIP_MARGIN, margin_bound

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
        from ..compensation.blocks import MARGINS

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
        from ..simulation.virtual_machine import REALISTIC, simulate

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
    from ..compensation.blocks import block_starts, judge, with_repeatability

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
