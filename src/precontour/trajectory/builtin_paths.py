"""Built-in test paths: parametric five-axis tool paths sampled densely into a ToolPath.

Each path is a closed-form tool tip P(u) (mm, workpiece frame) and orientation O(u) for
u in [0, 1], sampled at ``n_points`` equally spaced u. Orientations given by tilt A and turn
C angles use the A-C trunnion's convention O = (sin A sin C, -sin A cos C, cos A) (spec
section 1), so A and C below are what the zhang2013 machine commands; ``cone`` and ``fan``
are defined by their geometry in the workpiece frame.
"""

from __future__ import annotations

import numpy as np

from ..defaults import BUILTIN_PATHS
from ..errors import InputError, plain
from ..toolpath import ToolPath

# BUILTIN_PATHS, the names accepted by :func:`builtin_path`, is defined in precontour.defaults.


def _orientation(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(A) * np.sin(C), -np.sin(A) * np.cos(C), np.cos(A)], axis=-1)


def paper_path(n_points: int = 500) -> ToolPath:
    """A sculptured curve like the paper's test path (Zhang et al. 2013, Figs. 7-8).

    For u in [0, 1]::

        Px = -50 cos(pi u)                                  (-50 .. 50 mm)
        Py =  30 sin(2.5 pi u + 0.6 sin(2 pi u))            (-30 .. 30 mm, varying curvature)
        Pz =  20 - 20 cos(2 pi u) * (0.7 + 0.3 u)           (about 0 .. 40 mm)
        A  =  0.25 + 1.25 sin(pi u)^2                       (0.25 .. 1.5 rad)
        C  = -1.0 + 2.0 u - 0.3 sin(2 pi u)                 (-1 .. 1 rad, sweeps 2 rad)

    About 100 x 60 x 37 mm and 212 mm long, about 2.6 s at 100 mm/s on zhang2013; the tip
    stays 18 to 58 mm from the C axis and A never comes near 0.
    """
    u = np.linspace(0.0, 1.0, n_points)
    P = np.stack([-50.0 * np.cos(np.pi * u),
                  30.0 * np.sin(2.5 * np.pi * u + 0.6 * np.sin(2 * np.pi * u)),
                  20.0 - 20.0 * np.cos(2 * np.pi * u) * (0.7 + 0.3 * u)], axis=-1)
    A = 0.25 + 1.25 * np.sin(np.pi * u) ** 2
    C = -1.0 + 2.0 * u - 0.3 * np.sin(2 * np.pi * u)
    return ToolPath(P=P, O=_orientation(A, C), source="<built-in path paper>")


def circle_path(n_points: int = 400, *, radius: float = 50.0, tilt: float = 0.5,
                tilt_amplitude: float = 0.25) -> ToolPath:
    """A circle test in the spirit of ISO 230-4, run with simultaneous rotary motion.

    The tool tip goes once round a horizontal circle of ``radius`` (mm, default 50) about
    the C axis while the tool leans back along the circle, against the direction of travel,
    with a varying tilt, so the table turns a full revolution and tilts back and forth::

        phi = 2 pi u,  P = (radius cos phi, radius sin phi, 0)
        A = tilt + tilt_amplitude sin(2 phi),  C = phi     (rad; defaults 0.5 and 0.25)
    """
    if not radius > 0:
        raise InputError(f"radius must be > 0 mm, got {plain(radius)!r}", field="radius")
    u = np.linspace(0.0, 1.0, n_points)
    phi = 2 * np.pi * u
    P = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros_like(phi)], axis=-1)
    A = tilt + tilt_amplitude * np.sin(2 * phi)
    return ToolPath(P=P, O=_orientation(A, phi), source="<built-in path circle>")


def cone_path(n_points: int = 400, *, diameter: float = 80.0, half_angle: float = 15.0,
              tilt: float = 10.0) -> ToolPath:
    """Flank finishing of a cone frustum, in the spirit of NAS 979 (and ISO 10791-7).

    The NAS 979 test piece is a cone frustum with a 15 deg half-apex angle whose axis is
    inclined 10 deg from the machine's vertical; it is finished by the flank of the tool, so
    the tool axis lies along a generator of the cone and the tip runs round its base. Here:
    base circle of ``diameter`` (mm, default 80) at z = 0 in the cone's own frame, tool axis
    along the generator (leaning ``half_angle`` deg inward), and the whole cone rotated by
    ``tilt`` deg about the x axis::

        phi = 2 pi u
        P_cone = (r cos phi, r sin phi, 0),  r = diameter / 2
        O_cone = (-sin h cos phi, -sin h sin phi, cos h),  h = half_angle
        P = R_x(tilt) P_cone,  O = R_x(tilt) O_cone

    The tool's tilt from vertical varies between |half_angle - tilt| and half_angle + tilt
    (5 and 25 deg by default), and C turns a full revolution.
    """
    if not diameter > 0:
        raise InputError(f"diameter must be > 0 mm, got {plain(diameter)!r}", field="diameter")
    if not 0 < half_angle < 90:
        raise InputError(f"half_angle must be in (0, 90) deg, got {plain(half_angle)!r}",
                         field="half_angle")
    if abs(half_angle - tilt) < 2.0:
        raise InputError(f"|half_angle - tilt| must be >= 2 deg (the tool would pass "
                         f"within reach of vertical), got {abs(half_angle - tilt):g}",
                         field="tilt")
    u = np.linspace(0.0, 1.0, n_points)
    phi = 2 * np.pi * u
    h, b, r = np.radians(half_angle), np.radians(tilt), diameter / 2
    P = np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(phi)], axis=-1)
    O = np.stack([-np.sin(h) * np.cos(phi), -np.sin(h) * np.sin(phi),
                  np.full_like(phi, np.cos(h))], axis=-1)
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return ToolPath(P=P @ Rx.T, O=O @ Rx.T, source="<built-in path cone>")


def fan_path(n_points: int = 300, *, length: float = 80.0, fan_angle: float = 0.6) -> ToolPath:
    """A fan-shaped sweep like flank milling of a ruled surface.

    The tip runs along a gently curved line while the tool fans sideways out to
    ``fan_angle`` (rad) on one side, back through vertical, out to the other side and back::

        P = (length (u - 1/2), 8 sin(pi u), 0)              (mm; default length 80)
        beta = fan_angle sin(2 pi u)
        O = (0, sin beta, cos beta)

    The orientation stays in the y-z plane and passes exactly through vertical (A = 0)
    twice: the A-C trunnion keeps C fixed and swings A through zero (A < 0 on the far side).
    """
    if not length > 0:
        raise InputError(f"length must be > 0 mm, got {plain(length)!r}", field="length")
    u = np.linspace(0.0, 1.0, n_points)
    beta = fan_angle * np.sin(2 * np.pi * u)
    P = np.stack([length * (u - 0.5), 8.0 * np.sin(np.pi * u), np.zeros_like(u)], axis=-1)
    O = np.stack([np.zeros_like(u), np.sin(beta), np.cos(beta)], axis=-1)
    return ToolPath(P=P, O=O, source="<built-in path fan>")


_FACTORIES = {"paper": paper_path, "circle": circle_path, "cone": cone_path, "fan": fan_path}


def builtin_path(name: str, **params) -> ToolPath:
    """The built-in tool path ``name``.

    Parameters
    ----------
    name : str
        One of :data:`BUILTIN_PATHS`: ``paper``, ``circle``, ``cone``, ``fan``.
    **params
        Passed to its factory (:func:`paper_path`, :func:`circle_path`, :func:`cone_path`,
        :func:`fan_path`).

    Returns
    -------
    ToolPath
        Tool tip points and orientations, in the workpiece frame.
    """
    try:
        factory = _FACTORIES[name]
    except KeyError:
        raise InputError(f"unknown built-in path {name!r}; choose one of "
                         f"{', '.join(BUILTIN_PATHS)}") from None
    try:
        return factory(**params)
    except TypeError as exc:
        raise InputError(f"built-in path {name!r}: {exc}") from None
