"""Identification motion: a safe excitation of each axis, then of all axes together.

Per axis: jerk-limited steps of several sizes with settling dwells, reversals at three speeds
(friction on both sides of zero speed), and passes back and forth at a drift speed with a
multi-sine on it (Schroeder phases, 0.5 to 80 Hz; the speed stays away from zero within a pass,
so friction stays at its Coulomb level and the loop in its linear regime). Velocity,
acceleration and jerk stay within a fraction ``safety`` of the drive's limits. One axis at a
time (the others at rest), then the drift multi-sines of all five axes at once (interleaved
frequency grids, so that the axes stay uncorrelated). Moves stay within +-``travel`` of the
start, and within each axis's travel (the machine file's ``p_min``/``p_max`` and tilt travel,
the tilt axis within +-180 deg, and otherwise the largest coordinate a trajectory file holds):
a travel asked for that does not fit is refused, the default one is shortened to fit. The
motion is checked against the promised fraction of the limits before it is returned, and its
length is estimated and checked against the sample limit before any sample is made.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..defaults import DEFAULT_SAFETY, DEFAULT_TRAVEL_LINEAR, DEFAULT_TRAVEL_ROTARY
from ..errors import InputError, MachineLimitError, notice
from ..machine.drives import AXES, ROTARY_AXES
from ..tables import (MAX_LINEAR, MAX_ROTARY, check_output_path, trajectory_columns,
                      write_columns, write_text)
from ..toolpath.writers import ProgramInfo, gcode_program, halstreamer_lines
from ..trajectory.generate import check_sample_estimate
from ..trajectory.limits import AxisLimits, check_limits
from ..trajectory.sampled import Trajectory

# DEFAULT_TRAVEL_LINEAR, DEFAULT_TRAVEL_ROTARY (half travel, mm and rad) and DEFAULT_SAFETY
# (the fraction of each drive's v_max, a_max, j_max used) are defined in precontour.defaults.
#: Multi-sine band, Hz, and number of components.
MULTISINE_BAND = (0.5, 80.0)
MULTISINE_COMPONENTS = 24
#: Drift passes per multi-sine, each this long, s; the ripple's speed is below RIPPLE x drift.
PASSES = 4
PASS_DURATION = 2.5
RIPPLE = 0.7
#: Settling dwell after each step, s.
STEP_DWELL = 0.15
#: Fade-in / fade-out of the multi-sine, s.
FADE = 0.3
#: Share of an axis's travel the default excitation travel may use when it has to be
#: shortened to fit (margins of 5 % at both ends).
TRAVEL_SHARE = 0.9

# Peaks of the quintic smoothstep s(u) = 10u^3 - 15u^4 + 6u^5 and its derivatives on [0, 1].
_S1, _S2, _S3 = 1.875, 10.0 / np.sqrt(3.0), 60.0


def _smoothstep(u: np.ndarray) -> np.ndarray:
    return u**3 * (10.0 + u * (-15.0 + 6.0 * u))


class _Limits:
    def __init__(self, v: float, a: float, j: float):
        self.v, self.a, self.j = v, a, j


def _move_duration(distance: float, lim: _Limits) -> float:
    """Time of a rest-to-rest smoothstep move by ``distance`` at the velocity, acceleration
    and jerk limits (the largest of the three the smoothstep's peaks allow)."""
    d = abs(distance)
    return max(_S1 * d / lim.v, np.sqrt(_S2 * d / lim.a), np.cbrt(_S3 * d / lim.j))


def _move(distance: float, lim: _Limits, ts: float) -> np.ndarray:
    """Samples of a rest-to-rest move by ``distance`` within the limits (excluding the start)."""
    if distance == 0:
        return np.zeros(0)
    n = int(np.ceil(_move_duration(distance, lim) / ts))
    return distance * _smoothstep(np.arange(1, n + 1) / n)


def _dwell(seconds: float, ts: float) -> np.ndarray:
    return np.zeros(int(round(seconds / ts)))


def _steps_and_reversals(travel: float, lim: _Limits, ts: float) -> np.ndarray:
    """Offsets from the start: steps out and back, then reversals at three speeds."""
    pieces, pos = [], 0.0
    for target in (travel / 20, 0.0, -travel / 20, 0.0, travel / 2, 0.0, -travel / 2, 0.0):
        pieces += [pos + _move(target - pos, lim, ts), np.full(int(round(STEP_DWELL / ts)), target)]
        pos = target
    for fraction in (0.2, 0.5, 1.0):
        slow = _Limits(lim.v * fraction, lim.a, lim.j)
        for target in (travel / 4, -travel / 4, travel / 4, 0.0):
            pieces.append(pos + _move(target - pos, slow, ts))
            pos = target
        pieces.append(np.full(int(round(STEP_DWELL / ts)), pos))
    return np.concatenate(pieces)


def _multisine_velocity(duration: float, ts: float, grid_offset: int, seed: int
                        ) -> np.ndarray:
    """A unit-peak multi-sine (Schroeder phases) over the band, as a velocity shape."""
    t = np.arange(int(round(duration / ts))) * ts
    f = np.geomspace(*MULTISINE_BAND, MULTISINE_COMPONENTS)
    # Interleave the axes' grids by a fraction of the log spacing so they are not coherent.
    f = f * (f[1] / f[0]) ** (grid_offset / len(AXES))
    w = 2 * np.pi * f
    k = np.arange(1, f.size + 1)
    phase = -np.pi * k * (k - 1) / f.size + np.random.default_rng(seed).uniform(0, 0.3, f.size)
    # Flat velocity spectrum up to 5 Hz, then falling as 1/w^2 (flat jerk), as the limits need.
    amp = np.minimum(1.0, (2 * np.pi * 5.0 / w) ** 2)
    m = np.cos(np.outer(t, w) + phase) @ amp
    return m / np.max(np.abs(m))


def _pass_duration(travel: float, lim: _Limits) -> float:
    """Duration of a drift pass over 2 ``travel``: :data:`PASS_DURATION`, or longer where the
    drift speed that covers the pass in that time would leave no room for the ripple within
    the velocity limit (the speed is v0 (1 + ripple), and the fades cost FADE of the time)."""
    v_top = lim.v / (1.0 + RIPPLE)
    if 2 * travel / PASS_DURATION <= v_top:
        return PASS_DURATION
    return 2 * travel / v_top + FADE


def _drift_multisine(travel: float, lim: _Limits, ts: float, grid_offset: int, seed: int
                     ) -> np.ndarray:
    """Passes back and forth over [-travel, travel] at a drift speed v0 with a multi-sine on it.

    The multi-sine's velocity stays below :data:`RIPPLE` v0, so the speed never reaches zero
    within a pass: friction stays on one side (Coulomb level, not stick-slip) and the motion is
    in the drive's linear regime, apart from the turn-arounds between passes. Each pass lasts
    :func:`_pass_duration`; a smooth correction lands it exactly on the far end, and should
    that correction (the drift's miss) take the pass beyond a limit, the pass is made longer
    until it does not.
    """
    duration = _pass_duration(travel, lim)
    for _ in range(40):
        passes = _drift_passes(travel, lim, ts, grid_offset, seed, duration)
        if passes is not None:
            break
        duration *= 1.2
    else:  # pragma: no cover - each lengthening lowers the drift speed and the miss
        raise MachineLimitError("the excitation's drift passes cannot keep the limits")
    pieces = [_move(-travel, lim, ts)]
    pos = -travel
    for path in passes:
        pieces.append(pos + path)
        pos = pos + path[-1]
    pieces.append(pos + _move(-pos, lim, ts))
    return np.concatenate(pieces)


def _drift_passes(travel, lim, ts, grid_offset, seed, duration):
    """The :data:`PASSES` drift passes of ``duration`` each (offsets from each pass's start),
    or None when one of them leaves the velocity, acceleration or jerk limit."""
    v0 = min(lim.v / (1.0 + RIPPLE), 2 * travel / duration)
    passes = []
    for i in range(PASSES):
        direction = 1.0 if i % 2 == 0 else -1.0
        m = _multisine_velocity(duration, ts, grid_offset, seed + i)
        # The ripple's own acceleration and jerk within the limits (m is smooth and sampled
        # finely, so finite differences measure them).
        d1 = np.abs(np.diff(m)).max() / ts
        d2 = np.abs(np.diff(m, 2)).max() / ts**2
        ripple = min(RIPPLE * v0, 0.5 * lim.a / d1, 0.5 * lim.j / d2)
        nf = int(round(FADE / ts))
        envelope = np.ones(m.size)
        envelope[:nf] = _smoothstep(np.arange(nf) / nf)
        envelope[-nf:] = envelope[:nf][::-1]
        v = direction * envelope * (v0 + ripple * m * envelope)
        path = np.cumsum(v) * ts
        # Land exactly on the far end with a smooth correction of the drift's small miss.
        target = direction * 2 * travel
        path = path + (target - path[-1]) * _smoothstep(np.linspace(0.0, 1.0, path.size))
        # at rest before and after the pass, as between the moves around it
        padded = np.concatenate([np.zeros(3), path, np.full(3, path[-1])])
        for order, limit in ((1, lim.v), (2, lim.a), (3, lim.j)):
            if np.abs(np.diff(padded, order)).max() / ts**order > limit:
                return None
        passes.append(path)
    return passes


def _axis_samples(travel: float, lim: _Limits, ts: float) -> float:
    """Fewest samples the excitation of one axis can have (steps and reversals, the drift
    passes, the lead dwells), from the move and pass durations alone."""
    steps = 4 * _move_duration(travel / 20, lim) + 4 * _move_duration(travel / 2, lim)
    for fraction in (0.2, 0.5, 1.0):
        slow = _Limits(lim.v * fraction, lim.a, lim.j)
        steps += 2 * _move_duration(travel / 4, slow) + 2 * _move_duration(travel / 2, slow)
    drift = 2 * _move_duration(travel, lim) + PASSES * _pass_duration(travel, lim)
    return (steps + 11 * STEP_DWELL + 0.2) / ts + drift / ts


def excitation_travel(machine, axes: tuple[str, ...] = AXES, *, travel: dict | None = None,
                      start=None) -> tuple[np.ndarray, dict]:
    """The excitation's centre (5,) and half travel per axis, within each axis's travel.

    ``travel`` gives the half travels asked for (mm, rad); one that does not fit in the
    axis's travel is refused, naming the axis and the travel. The others get
    :data:`DEFAULT_TRAVEL_LINEAR` / :data:`DEFAULT_TRAVEL_ROTARY`, shortened (with a notice)
    to :data:`TRAVEL_SHARE` of the axis's travel where that is less. The centre is ``start``
    (default zeros), moved where needed so that centre +- half travel fits the axis's travel.
    An axis's travel is the machine's (:class:`~precontour.trajectory.limits.AxisLimits`:
    ``p_min``/``p_max``, the tilt travel, +-180 deg at most for the tilt axis) and at most
    :data:`~precontour.tables.MAX_LINEAR` / :data:`~precontour.tables.MAX_ROTARY`.
    """
    travel = dict(travel or {})
    q0 = np.zeros(len(AXES)) if start is None else np.asarray(start, float).copy()
    bounds = AxisLimits.from_machine(machine)
    half = {}
    for axis in axes:
        i = AXES.index(axis)
        rotary = axis in ROTARY_AXES
        name, unit = machine.axis_names[i], ("rad" if rotary else "mm")
        option = "--travel-rotary" if rotary else "--travel-linear"
        largest = MAX_ROTARY if rotary else MAX_LINEAR
        lo = max(float(bounds.position_min[i]), -largest)
        hi = min(float(bounds.position_max[i]), largest)
        where = (f"the {name} axis's travel [{lo:.6g}, {hi:.6g}] {unit}"
                 + ("" if np.isfinite(bounds.position_min[i]) or
                    np.isfinite(bounds.position_max[i]) else
                    " (the machine file gives none: the largest coordinate a trajectory "
                    "file holds)"))
        if axis in travel:
            value = float(travel[axis])
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name}: half travel must be a positive number, got "
                                 f"{travel[axis]!r}", field=option)
            if not 2 * value <= hi - lo:
                raise InputError(f"{name}: a half travel of {value:g} {unit} does not fit in "
                                 f"{where}; give at most {0.5 * (hi - lo):.6g}", field=option)
        else:
            value = DEFAULT_TRAVEL_ROTARY if rotary else DEFAULT_TRAVEL_LINEAR
            if not 2 * value <= TRAVEL_SHARE * (hi - lo):
                shorter = 0.5 * TRAVEL_SHARE * (hi - lo)
                notice(f"excitation of {name}: half travel {shorter:.6g} {unit} instead of "
                       f"{value:g} {unit}, to stay within {where}")
                value = shorter
        half[axis] = value
        q0[i] = min(max(q0[i], lo + value), hi - value)
    return q0, half


def excitation_trajectory(machine, *, travel: dict | None = None, safety: float = DEFAULT_SAFETY,
                          axes: tuple[str, ...] = AXES, start=None,
                          max_samples: int | None = None) -> Trajectory:
    """The identification motion for ``machine`` at its servo period.

    Parameters
    ----------
    machine : Machine
        Drive limits ``v_max``, ``a_max``, ``j_max`` (required for every moved axis) and the
        axes' travel (drives' ``p_min``/``p_max``, the tilt travel), if any.
    travel : dict, optional
        Half travel per axis name (mm or rad), each refused when it does not fit in the
        axis's travel; the others :data:`DEFAULT_TRAVEL_LINEAR`, :data:`DEFAULT_TRAVEL_ROTARY`,
        shortened to fit (see :func:`excitation_travel`).
    safety : float
        Fraction (0, 1] of the velocity, acceleration and jerk limits used.
    axes : tuple of str
        Axes to excite (the others stay at ``start``).
    start : array_like of shape (5,), optional
        Start and centre position (default: zeros, moved into an axis's travel if needed).
    max_samples : int, optional
        Refuse a motion estimated longer, before making it (default: sized to this machine's
        memory, as for trajectories).
    """
    if not 0.0 < safety <= 1.0:
        raise InputError(f"must be in (0, 1], got {safety!r}", field="safety")
    ts = machine.servo_period
    for axis in axes:
        drive = machine.drive(axis)
        missing = [k for k in ("v_max", "a_max", "j_max") if getattr(drive, k) is None]
        if missing:
            # drive.axis: the machine file's letter (B of a B-C machine), not the q slot
            raise InputError(f"drive {drive.axis} has no {missing[0]}; the excitation stays "
                             "within the drive limits, so give them in the machine file",
                             source=machine.source, field=f"drives.{drive.axis}.{missing[0]}")
    q0, half = excitation_travel(machine, axes, travel=travel, start=start)
    limits = {axis: _Limits(safety * machine.drive(axis).v_max, safety * machine.drive(axis).a_max,
                            safety * machine.drive(axis).j_max) for axis in axes}
    singles = [_axis_samples(half[a], limits[a], ts) for a in axes]
    together = max(PASSES * _pass_duration(half[a], limits[a]) / ts for a in axes)
    check_sample_estimate(sum(singles) + together, max_samples,
                          "half travel " + ", ".join(
                              f"{machine.axis_names[AXES.index(a)]} {half[a]:g}" for a in axes)
                          + f" at {safety:g} of the drive limits, sampled every {ts:g} s",
                          what="excitation", option=None, source=machine.source)
    segments = []
    lead = _dwell(0.1, ts)
    for axis in axes:
        offsets = np.concatenate([lead, _steps_and_reversals(half[axis], limits[axis], ts),
                                  _drift_multisine(half[axis], limits[axis], ts, AXES.index(axis),
                                                   10 * AXES.index(axis)), lead])
        block = np.tile(q0, (offsets.size, 1))
        block[:, AXES.index(axis)] += offsets
        segments.append(block)
    together = [_drift_multisine(half[axis], limits[axis], ts, AXES.index(axis),
                                 100 + 10 * AXES.index(axis))
                for axis in axes]
    n = max(s.size for s in together)
    block = np.tile(q0, (n + 2 * lead.size, 1))
    for axis, s in zip(axes, together):
        block[lead.size:lead.size + s.size, AXES.index(axis)] += s
    segments.append(block)
    q = np.concatenate(segments)
    _check_promise(q, ts, machine, safety, axes)
    return Trajectory(t=np.arange(q.shape[0]) * ts, q=q)


def _check_promise(q: np.ndarray, ts: float, machine, safety: float, axes) -> None:
    """The motion keeps ``safety`` of the velocity, acceleration and jerk limits and each
    axis's travel (as ``export`` checks them), or this is a bug: say so rather than write it."""
    full = AxisLimits.from_machine(machine)
    scaled = AxisLimits(position_min=full.position_min, position_max=full.position_max,
                        velocity=safety * full.velocity, acceleration=safety * full.acceleration,
                        jerk=safety * full.jerk, axis_names=full.axis_names)
    check = check_limits(q, ts, scaled)
    if not check.ok:  # pragma: no cover - guarded by construction
        raise MachineLimitError(f"the excitation of {''.join(axes)} on {machine.name} would "
                                f"exceed {safety:g} of the machine's limits ({check.format()})")


#: Output suffixes of :func:`write_excitation`: column files, and NC programs.
TABLE_SUFFIXES: tuple[str, ...] = (".csv", ".npz", ".parquet")
PROGRAM_SUFFIXES: dict[str, str] = {".ngc": "gcode", ".txt": "halstreamer"}


def check_excitation_output(path, inputs=()) -> Path:
    """Check, before computing, that :func:`write_excitation` can write ``path`` (a known
    extension, a writable place, no input)."""
    return check_output_path(path, inputs=inputs, suffixes=TABLE_SUFFIXES + tuple(PROGRAM_SUFFIXES))


def write_excitation(path, traj: Trajectory, machine, *, inputs=()) -> None:
    """Write the excitation as ``t,X,Y,Z,A,C`` columns, or as a G-code (``.ngc``) or LinuxCNC
    halstreamer (``.txt``) program (:mod:`precontour.toolpath.writers`)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in TABLE_SUFFIXES:
        write_columns(path, trajectory_columns(traj, machine.axis_names), inputs=inputs)
        return
    if suffix not in PROGRAM_SUFFIXES:
        raise InputError(f"unsupported output type {suffix or '(none)'!r}; use one of "
                         f"{', '.join(TABLE_SUFFIXES + tuple(PROGRAM_SUFFIXES))}",
                         source=str(path))
    info = ProgramInfo(machine=machine.name, controller="",
                       method="identification excitation (precontour excite)", source="")
    if PROGRAM_SUFFIXES[suffix] == "halstreamer":
        text = halstreamer_lines(traj.q, traj.ts, info=info)
    else:
        text = gcode_program(traj.t, traj.q, info=info, axis_names=machine.axis_names).text
    write_text(path, text, inputs=inputs)
