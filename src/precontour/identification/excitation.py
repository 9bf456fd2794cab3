"""Identification motion: a safe excitation of each axis, then of all axes together.

Per axis: jerk-limited steps of several sizes with settling dwells, reversals at three speeds
(friction on both sides of zero speed), and passes back and forth at a drift speed with a
multi-sine on it (Schroeder phases, 0.5 to 80 Hz; the speed stays away from zero within a pass,
so friction stays at its Coulomb level and the loop in its linear regime). Velocity,
acceleration and jerk stay within a fraction ``safety`` of the drive's limits. One axis at a
time (the others at rest), then the drift multi-sines of all five axes at once (interleaved
frequency grids, so that the axes stay uncorrelated). Moves stay within +-``travel`` of the
start (and within the A axis's travel, if the machine has one).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..defaults import DEFAULT_SAFETY, DEFAULT_TRAVEL_LINEAR, DEFAULT_TRAVEL_ROTARY
from ..errors import InputError
from ..machine.drives import AXES, ROTARY_AXES
from ..tables import trajectory_columns, write_columns, write_text
from ..toolpath.writers import ProgramInfo, gcode_program, halstreamer_lines
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

# Peaks of the quintic smoothstep s(u) = 10u^3 - 15u^4 + 6u^5 and its derivatives on [0, 1].
_S1, _S2, _S3 = 1.875, 10.0 / np.sqrt(3.0), 60.0


def _smoothstep(u: np.ndarray) -> np.ndarray:
    return u**3 * (10.0 + u * (-15.0 + 6.0 * u))


class _Limits:
    def __init__(self, v: float, a: float, j: float):
        self.v, self.a, self.j = v, a, j


def _move(distance: float, lim: _Limits, ts: float) -> np.ndarray:
    """Samples of a rest-to-rest move by ``distance`` within the limits (excluding the start)."""
    d = abs(distance)
    if d == 0:
        return np.zeros(0)
    duration = max(_S1 * d / lim.v, np.sqrt(_S2 * d / lim.a), np.cbrt(_S3 * d / lim.j))
    n = int(np.ceil(duration / ts))
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


def _drift_multisine(travel: float, lim: _Limits, ts: float, grid_offset: int, seed: int
                     ) -> np.ndarray:
    """Passes back and forth over [-travel, travel] at a drift speed v0 with a multi-sine on it.

    The multi-sine's velocity stays below :data:`RIPPLE` v0, so the speed never reaches zero
    within a pass: friction stays on one side (Coulomb level, not stick-slip) and the motion is
    in the drive's linear regime, apart from the turn-arounds between passes.
    """
    v0 = min(lim.v / (1.0 + RIPPLE), 2 * travel / PASS_DURATION)
    pieces = [_move(-travel, lim, ts)]
    pos = -travel
    for i in range(PASSES):
        direction = 1.0 if i % 2 == 0 else -1.0
        m = _multisine_velocity(PASS_DURATION, ts, grid_offset, seed + i)
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
        pieces.append(pos + path)
        pos = pos + target
    pieces.append(pos + _move(-pos, lim, ts))
    return np.concatenate(pieces)


def excitation_trajectory(machine, *, travel: dict | None = None, safety: float = DEFAULT_SAFETY,
                          axes: tuple[str, ...] = AXES, start=None) -> Trajectory:
    """The identification motion for ``machine`` at its servo period.

    Parameters
    ----------
    machine : Machine
        Drive limits ``v_max``, ``a_max``, ``j_max`` (required for every moved axis) and the
        kinematics' A travel (``a_min``/``a_max``), if any.
    travel : dict, optional
        Half travel per axis name (mm or rad); defaults :data:`DEFAULT_TRAVEL_LINEAR`,
        :data:`DEFAULT_TRAVEL_ROTARY`.
    safety : float
        Fraction (0, 1] of the velocity, acceleration and jerk limits used.
    axes : tuple of str
        Axes to excite (the others stay at ``start``).
    start : array_like of shape (5,), optional
        Start and centre position (default: zeros, moved into the A travel if needed).
    """
    if not 0.0 < safety <= 1.0:
        raise InputError(f"must be in (0, 1], got {safety!r}", field="safety")
    ts = machine.servo_period
    q0 = np.zeros(len(AXES)) if start is None else np.asarray(start, float).copy()
    half = {}
    for axis in axes:
        drive = machine.drive(axis)
        missing = [k for k in ("v_max", "a_max", "j_max") if getattr(drive, k) is None]
        if missing:
            raise InputError(f"drive {axis} has no {missing[0]}; the excitation stays within "
                             "the drive limits, so give them in the machine file",
                             source=machine.source, field=f"drives.{axis}.{missing[0]}")
        default = DEFAULT_TRAVEL_ROTARY if axis in ROTARY_AXES else DEFAULT_TRAVEL_LINEAR
        half[axis] = float((travel or {}).get(axis, default))
    kin = machine.kinematics
    if "A" in half and (getattr(kin, "a_min", None) is not None or getattr(kin, "a_max", None) is not None):
        lo = -np.inf if kin.a_min is None else kin.a_min
        hi = np.inf if kin.a_max is None else kin.a_max
        centre = min(max(q0[3], lo + half["A"]), hi - half["A"])
        if not lo <= centre - half["A"] and centre + half["A"] <= hi:
            centre = 0.5 * (lo + hi)
            half["A"] = min(half["A"], 0.45 * (hi - lo))
        q0[3] = centre
    limits = {axis: _Limits(safety * machine.drive(axis).v_max, safety * machine.drive(axis).a_max,
                            safety * machine.drive(axis).j_max) for axis in axes}
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
    return Trajectory(t=np.arange(q.shape[0]) * ts, q=q)


#: Output suffixes of :func:`write_excitation`: column files, and NC programs.
TABLE_SUFFIXES: tuple[str, ...] = (".csv", ".npz", ".parquet")
PROGRAM_SUFFIXES: dict[str, str] = {".ngc": "gcode", ".txt": "halstreamer"}


def write_excitation(path, traj: Trajectory, machine, *, inputs=()) -> None:
    """Write the excitation as ``t,X,Y,Z,A,C`` columns, or as a G-code (``.ngc``) or LinuxCNC
    halstreamer (``.txt``) program (:mod:`precontour.toolpath.writers`)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in TABLE_SUFFIXES:
        write_columns(path, trajectory_columns(traj), inputs=inputs)
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
