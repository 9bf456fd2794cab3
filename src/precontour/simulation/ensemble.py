"""An ensemble of virtual machines: the realistic machine and draws of its uncertain parts.

Where an axis stops or reverses under friction, the realistic virtual machine's answer to a
command is decided by nanometres: static friction holds the axis wherever it comes to rest,
and a decision taken on that one exact simulation (which learning pass to keep, which
settling delay, which step of a line search) is a coin toss (issue 21: on `paper` / `pid-high`
the command learning kept left 0.48, 0.51, 1.37 or 1.89 um depending on 1e-9 mm of input
noise). A real machine's scatter is far larger: its friction drifts by tens of percent, its
inertia and damping are known to a few percent, its encoder quantises and is noisy.

This module owns the draws of such a machine (:class:`MachineEnsemble`, deterministic given
its seed) and the ensemble as a machine model, commands (N, 5) in and one actual motion per
draw (D, N, 5) out (:func:`ensemble_actual`), for compensation to take its decisions on.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from ..errors import is_whole_number
from ..machine.controllers import Controller
from ..machine.machine_file import Machine
from .virtual_machine import REALISTIC, simulate_draws

__all__ = ["MachineEnsemble", "ensemble_actual"]

#: Samples per block of a draw's encoder noise. The noise of sample k of a program is a
#: function of (seed, draw, k) alone: block 0 continues the draw's own generator (so a
#: program of at most this many samples reads what it read before blocks existed), block
#: c > 0 has a generator of its own, seeded (seed, draw, c). Why: learning by segment
#: (:mod:`precontour.compensation.segments`) runs the machine on a stretch of the program,
#: and its decisions must be taken on the machines that ``run`` then checks the whole program
#: on, reading the same noise at the same sample; drawn afresh for each stretch, every
#: stop's stick-slip was a new coin, and a segment's fallback did not hold on the check.
NOISE_BLOCK = 1 << 19


@dataclass(frozen=True)
class MachineEnsemble:
    """Draws of the realistic virtual machine (:data:`~.virtual_machine.REALISTIC`).

    Draw 0 is the machine itself (the machine file's drives, no encoder) when ``nominal``;
    every other draw scales each axis's static and Coulomb friction torques (both signs of the
    speed, independently), its inertia J and its damping B by factors drawn uniformly within
    the spreads, and reads each axis through an encoder of ``encoder_resolution`` whose grid
    origin is drawn uniformly within one count and whose readings carry normal noise of
    ``encoder_noise`` rms. The controller and the friction feed-forward keep the machine
    file's values: these are the true machine's departures from the model.

    Why these spreads by default (+-2 % friction, +-1 % J and B, the encoder): they make
    where friction holds an axis a different coin on every draw, which is what a decision must
    not hang on, without a scatter that no command can follow. With the issue's example of
    +-10 % friction and +-5 % J and B, on `paper` / `pid-high` every command learning tries
    has the same worst draw to within 3 % (12.5-12.9 um: the friction torque the
    feed-forward misses, on the draw where it misses most), so the worst draw cannot tell
    them apart; learning decided on it removed, on the realistic machine, 84.7 % of the max
    tip error on `paper`, 75.0 % on `fan25`, 85.8 % on `_fan_reversals` and 39.6 % on
    `cone` (pid-high, three input draws each, every draw alike), against 98.5 / 93.9 / 85.9 /
    77.3 % (medians) decided on these spreads, and did no better on machines it never saw
    (friction +-10 %, J, B +-5 %: 83.8 / 63.9 / 62.0 / 48.2 % of the max against
    87.0 / 81.4 / 61.8 / 63.8 %). Measured with ``scripts/measure_robust.py``'s set-up.

    Attributes
    ----------
    draws : int
        Number of machines, >= 1.
    friction_spread : float
        Relative half-width of the friction torque factors (0.02: within +-2 %), in [0, 1).
    inertia_spread, damping_spread : float
        Relative half-widths of the J and B factors, in [0, 1).
    encoder_resolution : tuple of (float, float)
        Encoder grid, linear axes (mm) and rotary axes (rad); (0, 0): no quantisation. The
        default, 10 nm and 0.1 urad, is about a 2^20-count motor encoder on the built-in
        machine's ball screws (1.59 mm/rad: 9.5 nm per count).
    encoder_noise : tuple of (float, float)
        Rms noise of each reading, linear (mm) and rotary (rad).
    seed : int
        Seed of the draws: the same seed gives the same machines.
    nominal : bool
        Whether draw 0 is the unperturbed machine.
    repeat : int
        Which run of these machines: 0, the draws' own encoder noise; k > 0, the same machines
        (friction, inertia, damping, encoder grid) read through encoder noise drawn afresh,
        from generators seeded (seed, draw, block, k) (:meth:`rerun`). Why: where an axis
        rests under friction with a quantised encoder, a machine does not repeat itself, and
        how much one source line's error changes when the same machine runs the same command
        again bounds what any comparison of two commands there can tell (issue 21).
    """

    draws: int = 5
    friction_spread: float = 0.02
    inertia_spread: float = 0.01
    damping_spread: float = 0.01
    encoder_resolution: tuple[float, float] = (1e-5, 1e-7)
    encoder_noise: tuple[float, float] = (2e-6, 2e-8)
    seed: int = 0
    nominal: bool = True
    repeat: int = 0

    def __post_init__(self):
        if not is_whole_number(self.draws) or self.draws < 1:
            raise ValueError(f"draws must be an integer >= 1, got {self.draws!r}")
        for name in ("friction_spread", "inertia_spread", "damping_spread"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and 0 <= value < 1):
                raise ValueError(f"{name} must be within [0, 1), got {value!r}")
        for name in ("encoder_resolution", "encoder_noise"):
            value = tuple(getattr(self, name))
            if len(value) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                          and v >= 0 for v in value):
                raise ValueError(f"{name} must be two finite numbers >= 0 (linear mm, rotary "
                                 f"rad), got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        for name in ("seed", "repeat"):
            value = getattr(self, name)
            if not is_whole_number(value) or value < 0:
                raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
            object.__setattr__(self, name, int(value))
        object.__setattr__(self, "draws", int(self.draws))

    @property
    def rerun_differs(self) -> bool:
        """Whether :meth:`rerun` is another run: some draw reads through encoder noise, and
        this is not itself a rerun (whose rerun would be the same run)."""
        return (self.draws > (1 if self.nominal else 0) and any(self.encoder_noise)
                and not self.repeat)

    def rerun(self, repeat: int = 1) -> "MachineEnsemble":
        """The same machines run again: run ``repeat`` (> 0) of their encoder noise."""
        if not is_whole_number(repeat) or repeat < 1:
            raise ValueError(f"repeat must be an integer >= 1, got {repeat!r}")
        return replace(self, repeat=int(repeat))

    def options(self, n_samples: int, rotary=(False, False, False, True, True), *,
                start: int = 0) -> list[dict]:
        """The :func:`~.virtual_machine.simulate` options of each draw (beyond
        :data:`~.virtual_machine.REALISTIC`), for commands of ``n_samples`` samples, the
        program's samples ``start`` on (the encoder noise of those samples,
        :data:`NOISE_BLOCK`); ``rotary`` marks the axes whose encoder values are the rotary
        ones."""
        return [self.option(d, n_samples, rotary, start=start) for d in range(self.draws)]

    def option(self, draw: int, n_samples: int,
               rotary=(False, False, False, True, True), *, start: int = 0) -> dict:
        """The options of draw ``draw`` alone (:meth:`options`): one draw's encoder noise in
        memory at a time, for a long program checked draw by draw."""
        if not 0 <= draw < self.draws:
            raise ValueError(f"draw must be within [0, {self.draws}), got {draw!r}")
        if not is_whole_number(start) or start < 0:
            raise ValueError(f"start must be an integer >= 0, got {start!r}")
        if draw == 0 and self.nominal:
            return {}
        rotary = np.asarray(rotary, dtype=bool)
        # one generator per draw: a draw does not change with the number of draws
        rng = np.random.default_rng([self.seed, draw])
        option = dict(
            friction_scale=1.0 + self.friction_spread * rng.uniform(-1, 1, (2, 5)),
            inertia_scale=1.0 + self.inertia_spread * rng.uniform(-1, 1, 5),
            damping_scale=1.0 + self.damping_spread * rng.uniform(-1, 1, 5))
        resolution = np.where(rotary, self.encoder_resolution[1], self.encoder_resolution[0])
        noise = np.where(rotary, self.encoder_noise[1], self.encoder_noise[0])
        offsets = rng.uniform(0, 1, 5)
        if np.all(resolution > 0):
            option.update(encoder_resolution=resolution, encoder_offset=offsets * resolution)
        elif np.any(resolution > 0):
            raise ValueError("encoder_resolution must be 0 for both kinds of axis or "
                             "for neither")
        if np.any(noise > 0):
            option.update(encoder_noise=self._noise(rng, draw, int(start), n_samples) * noise)
        return option

    def _noise(self, rng: np.random.Generator, draw: int, start: int, n_samples: int
               ) -> np.ndarray:
        """Unit normal noise of the program's samples [start, start + n_samples) of draw
        ``draw``, block by block (:data:`NOISE_BLOCK`); ``rng``: the draw's generator, after
        its friction, inertia, damping and grid offsets."""
        stop = start + n_samples
        parts = []
        # (the block holding ``start`` at least, so that no samples give shape (0, 5))
        for block in range(start // NOISE_BLOCK, max(stop - 1, start) // NOISE_BLOCK + 1):
            first = block * NOISE_BLOCK
            if self.repeat:
                source = np.random.default_rng([self.seed, draw, block, self.repeat])
            else:
                source = rng if block == 0 else np.random.default_rng([self.seed, draw, block])
            # a generator's normals come in order: the block's first rows are what a longer
            # stretch of it would start with
            rows = source.standard_normal((min(NOISE_BLOCK, stop - first), 5))
            parts.append(rows[max(start - first, 0):])
        return np.concatenate(parts)

    def describe(self) -> str:
        """One line for tables and reports."""
        parts = [f"{self.draws} draw(s)" + (" (draw 0 the machine file's)" if self.nominal
                                            else ""),
                 f"friction +-{100 * self.friction_spread:g} %",
                 f"J +-{100 * self.inertia_spread:g} %", f"B +-{100 * self.damping_spread:g} %"]
        if any(self.encoder_resolution):
            parts.append(f"encoder {1e6 * self.encoder_resolution[0]:g} nm / "
                         f"{1e6 * self.encoder_resolution[1]:g} urad")
        if any(self.encoder_noise):
            parts.append(f"noise {1e6 * self.encoder_noise[0]:g} nm / "
                         f"{1e6 * self.encoder_noise[1]:g} urad rms")
        return ", ".join(parts) + f", seed {self.seed}" + (f", run {self.repeat}" if self.repeat
                                                            else "")


def ensemble_actual(t: np.ndarray, machine: Machine, controller: Controller | str,
                    ensemble: MachineEnsemble | None = None, *, start: int = 0):
    """The ensemble's machines at the times ``t`` as a model ``actual(q) -> q_act`` of
    commands (N, 5) to one actual motion per draw (D, N, 5), the draws run side by side
    (:func:`~.virtual_machine.simulate_draws`); ``actual.draw(q, d)``: draw ``d``'s alone.
    ``ensemble`` defaults to :class:`MachineEnsemble` (); ``start``: the program's sample at
    ``t[0]`` (a stretch of a longer program reads that stretch's encoder noise)."""
    ensemble = MachineEnsemble() if ensemble is None else ensemble
    t = np.asarray(t, dtype=float)
    rotary = [d.is_rotary for d in machine.drives]
    options = ensemble.options(t.size, rotary, start=start)

    def actual(q: np.ndarray) -> np.ndarray:
        return simulate_draws(t, q, machine, controller, options, **REALISTIC)

    actual.ensemble = ensemble

    # one draw alone, (N, 5): what learning's update from the worst draw runs
    # (compensation.stops.WORST_DRAW_STEPS), at one draw's cost
    def draw(q: np.ndarray, index: int) -> np.ndarray:
        return simulate_draws(t, q, machine, controller, [options[index]], **REALISTIC)[0]

    actual.draw = draw
    # the same machines run again (their encoder noise re-drawn), for the repeatability of
    # the uncompensated command's errors (compensation.blocks.with_repeatability); None where
    # a rerun is the same run
    def repeat(q: np.ndarray) -> np.ndarray:
        # built when called: its encoder noise is in memory only while it runs
        return ensemble_actual(t, machine, controller, ensemble.rerun(), start=start)(q)

    actual.repeat = repeat if ensemble.rerun_differs else None
    return actual
