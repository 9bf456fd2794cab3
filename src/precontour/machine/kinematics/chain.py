"""A five-axis machine as a kinematic chain, machine-file type ``chain``: each rotary axis with
its direction, a point of its line and whether the table (the part's side) or the head (the
tool's side) carries it, the way commercial controls describe every family (Sinumerik TRAORI's
types 24, 40 and 56, Heidenhain's kinematics table). Table-table, head-table and head-head
machines are all chains; the other types are presets of it (``chain_of`` builds the chain of
each, and tests/machine/test_chain.py checks that they are equal).

The chain. X, Y, Z put the spindle nose at N = (sX X, sY Y, sZ Z) (``linear_senses``: -1 where an
axis moves the table rather than the tool, which moves the tool the other way); at the zero pose
the tool points along +z and its tip is at N - t ez (t = ``tool_offset``). A rotary axis turns by
its command q right-handed about its ``direction`` (a unit vector; its sign is the axis's
sense of rotation) about the line through its ``point``: in the machine frame at the zero pose on
a table, relative to the spindle nose N on a head. A table axis turns the part, a head axis the
tool. P and O are in the workpiece frame: the machine frame moved with the table's axes, its
origin at ``workpiece_origin`` (machine frame, zero pose).

Supported: the C axis along the tool at the zero pose (direction +-z) and a tilt axis A
(direction +-x) or B (+-y) across it, arranged so that both orient the tool: on a table the C
axis carries the part and the tilt carries C; on a head the C axis carries the tilt, which
carries the spindle; or one of each. Then, with sigma = -1 for a table axis (it turns the part,
the tool turns the other way relative to it) and +1 for a head axis, the tool axis in the
workpiece frame is

    O = Rz(c) R(tilt) ez,   tilt = s sigma_tilt q_tilt,   c = e sigma_C q_C,

s and e the signs of the directions (R = Rx for A, Ry for B): the trunnions' orientation map,
whose path inverse (:class:`~._trunnion.TrunnionKinematics`: C unwrapped, the pole tilt = 0
bridged, the tilt sign chosen within its travel) this type shares.

Two tilts, A (direction +-x) and B (+-y) and no C, as on an A-B table (LinuxCNC's
xyzab_tdr_kins): each on the table or the head, and where both are on the same side
``carrier`` names the one that carries the other (on a table the one nearer the base, on a head
the one nearer the ram). The tool axis is then O = Ru(alpha) Rv(beta) ez, v the axis applied
first to the tool (a head axis before a table axis; of two head axes the one nearer the tool,
of two table axes the one nearer the base), u the other, alpha and beta their commands times
sign sigma: the map and path inverse of :class:`~._two_tilt.TwoTiltKinematics`, q = [X, Y, Z,
A, B] (:class:`TwoTiltChain`). Axes at other angles (nutating heads and tables) are refused,
not yet supported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import (TrunnionKinematics, rotary_pair, tilt_x_jacobian, tilt_x_orientation,
                        tilt_x_turn, tilt_y_jacobian, tilt_y_orientation, tilt_y_turn)
from ._two_tilt import TwoTiltKinematics

#: Where a rotary axis sits: carried by the table (turns the part) or by the head (the tool).
SIDES = ("table", "head")
_UNIT = {"A": 0, "B": 1, "C": 2}


@dataclass(frozen=True)
class RotaryAxis:
    """One rotary axis of a chain: ``letter`` (A, B or C), ``side`` (table or head), its unit
    ``direction`` (sign = sense of rotation) and a ``point`` of its line (mm; on a head relative
    to the spindle nose)."""

    letter: str
    side: str
    direction: tuple[float, float, float]
    point: tuple[float, float, float]

    @property
    def sign(self) -> float:
        """+1 or -1: the direction along its machine axis (x for A, y for B, z for C)."""
        return float(self.direction[_UNIT[self.letter]])

    @property
    def sigma(self) -> float:
        """-1 on a table (turning the part turns the tool the other way relative to it)."""
        return -1.0 if self.side == "table" else 1.0


def turn_about(x: np.ndarray, axis: RotaryAxis, angle: np.ndarray, *,
               direction: bool = False) -> np.ndarray:
    """Points x[..., 3] (or directions, ``direction``) turned by ``angle`` right-handed about
    ``axis``'s line through its point: with the axis along a machine axis, a rotation in one
    coordinate plane."""
    k = _UNIT[axis.letter]
    i, j = (k + 1) % 3, (k + 2) % 3
    angle = axis.sign * np.asarray(angle, dtype=float)  # about -e_k by q = about +e_k by -q
    s, c = np.sin(angle), np.cos(angle)
    ci, cj = (0.0, 0.0) if direction else (axis.point[i], axis.point[j])
    x = np.asarray(x, dtype=float)
    out = np.empty(np.broadcast_shapes(x.shape, angle.shape + (3,)))
    u, v = x[..., i] - ci, x[..., j] - cj
    out[..., i] = c * u - s * v + ci
    out[..., j] = s * u + c * v + cj
    out[..., k] = x[..., k]
    return out


class _ChainMotion:
    """Forward kinematics and the linear axes of a chain, from ``_head_axes()`` (the head
    axes from the one nearest the tool), ``_table_axes()`` (the table axes from the one
    carrying the part), each as (axis, slot), and the fields ``tool_offset``,
    ``linear_senses``, ``workpiece_origin``."""

    @property
    def rotary_axes(self) -> tuple[tuple[RotaryAxis, int], ...]:
        """The two rotary axes with their slots in q (3, 4)."""
        return tuple(sorted(self._head_axes() + self._table_axes(), key=lambda item: item[1]))

    def _tool(self, rotary: np.ndarray, direction: bool) -> np.ndarray:
        """The tip relative to the spindle nose (or the tool axis, ``direction``) in the
        machine frame: the head axes turn the zero-pose tool, the one nearest it first."""
        start = np.array([0.0, 0.0, 1.0]) if direction else np.array([0.0, 0.0,
                                                                      -self.tool_offset])
        x = np.broadcast_to(start, rotary.shape[:-1] + (3,))
        for axis, slot in self._head_axes():
            x = turn_about(x, axis, rotary[..., slot - 3], direction=direction)
        return x

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` (mm, rad) -> tool tip ``P[..., 3]``
        (mm) and unit orientation ``O[..., 3]`` in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        rotary = q[..., 3:]
        tip = q[..., :3] * np.asarray(self.linear_senses) + self._tool(rotary, False)
        axis = self._tool(rotary, True)
        # into the workpiece frame: undo the table axes, the one nearest the base first
        for table_axis, slot in reversed(self._table_axes()):
            tip = turn_about(tip, table_axis, -rotary[..., slot - 3])
            axis = turn_about(axis, table_axis, -rotary[..., slot - 3], direction=True)
        return tip - np.asarray(self.workpiece_origin), axis

    def linear_axes(self, P: np.ndarray, A, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` (workpiece frame)
        when the rotary axes stand at ``A`` (slot 3), ``C`` (slot 4; rad; or
        ``linear_axes(P, rotary[..., 2])``): what tool-centre-point control computes."""
        tilt, turn = rotary_pair(A, C)
        rotary = np.stack(np.broadcast_arrays(tilt, turn), axis=-1)
        tip = np.asarray(P, dtype=float) + np.asarray(self.workpiece_origin)
        for table_axis, slot in self._table_axes():
            tip = turn_about(tip, table_axis, rotary[..., slot - 3])
        nose = tip - self._tool(rotary, False)
        return nose * np.asarray(self.linear_senses)


@dataclass(frozen=True)
class ChainKinematics(_ChainMotion, TrunnionKinematics):
    """Kinematics of a chain (see the module docstring): ``tilt`` (A or B, slot 3) and ``turn``
    (C, slot 4) rotary axes, the tool length ``tool_offset`` (mm), ``linear_senses`` (+1/-1 for
    X, Y, Z), ``workpiece_origin`` (mm), and the tilt travel ``tilt_min``/``tilt_max`` (rad,
    ``None``: free; the tilt drive's ``p_min``/``p_max``)."""

    tilt: RotaryAxis
    turn: RotaryAxis
    tool_offset: float
    linear_senses: tuple[float, float, float] = (1.0, 1.0, 1.0)
    workpiece_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tilt_min: float | None = None
    tilt_max: float | None = None

    _TILT_FIELDS = ("tilt_min", "tilt_max")

    def __post_init__(self):
        check_chain(self.tilt, self.turn)

    @classmethod
    def from_table(cls, table):
        """The machine file's ``chain`` (a :class:`TwoTiltChain` where its axes are A and B)."""
        return chain_from_table(table)

    # ---------------------------------------------------------------- the trunnion hooks
    @property
    def axis_names(self) -> tuple[str, ...]:
        return ("X", "Y", "Z", self.tilt.letter, "C")

    @property
    def tilt_direction(self) -> float:
        return self.tilt.sign * self.tilt.sigma

    @property
    def turn_direction(self) -> float:
        return self.turn.sign * self.turn.sigma

    @property
    def _physical_orientation(self):
        return tilt_x_orientation if self.tilt.letter == "A" else tilt_y_orientation

    @property
    def _physical_jacobian(self):
        return tilt_x_jacobian if self.tilt.letter == "A" else tilt_y_jacobian

    @property
    def _physical_turn(self):
        return tilt_x_turn if self.tilt.letter == "A" else tilt_y_turn

    # ---------------------------------------------------------------- the chain
    def _head_axes(self) -> list[tuple[RotaryAxis, int]]:
        """Head axes from the one nearest the tool: (axis, slot)."""
        return [(a, s) for a, s in ((self.tilt, 3), (self.turn, 4)) if a.side == "head"]

    def _table_axes(self) -> list[tuple[RotaryAxis, int]]:
        """Table axes from the one carrying the part: (axis, slot)."""
        return [(a, s) for a, s in ((self.turn, 4), (self.tilt, 3)) if a.side == "table"]


@dataclass(frozen=True)
class TwoTiltChain(_ChainMotion, TwoTiltKinematics):
    """A chain of two tilts (see the module docstring): ``a`` (A, direction +-x, slot 3) and
    ``b`` (B, +-y, slot 4), ``carrier`` the letter of the one carrying the other where both
    are on the same side, the tool length ``tool_offset`` (mm), ``linear_senses``,
    ``workpiece_origin`` (mm), and the travels ``a_min`` ... ``b_max`` (rad, ``None``: free;
    the drives' ``p_min``/``p_max``)."""

    a: RotaryAxis
    b: RotaryAxis
    carrier: str
    tool_offset: float
    linear_senses: tuple[float, float, float] = (1.0, 1.0, 1.0)
    workpiece_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    a_min: float | None = None
    a_max: float | None = None
    b_min: float | None = None
    b_max: float | None = None

    def __post_init__(self):
        check_two_tilts(self.a, self.b, self.carrier)

    def _ordered(self) -> list[tuple[RotaryAxis, int]]:
        """Both axes, the carried one first."""
        pairs = [(self.a, 3), (self.b, 4)]
        return pairs if self.carrier == "B" else pairs[::-1]

    def _head_axes(self) -> list[tuple[RotaryAxis, int]]:
        return [(a, s) for a, s in self._ordered() if a.side == "head"]

    def _table_axes(self) -> list[tuple[RotaryAxis, int]]:
        return [(a, s) for a, s in self._ordered() if a.side == "table"]

    def _sequence(self) -> list[tuple[RotaryAxis, int]]:
        """The axes in the order they turn the tool axis into the workpiece frame: the head's
        from the tool outwards, then the table's from the base inwards."""
        return self._head_axes() + self._table_axes()[::-1]

    @property
    def _outer_slot(self) -> int:
        return self._sequence()[1][1]

    @property
    def _outer_x(self) -> bool:
        return self._sequence()[1][0].letter == "A"

    @property
    def _outer_sign(self) -> float:
        axis = self._sequence()[1][0]
        return axis.sign * axis.sigma

    @property
    def _inner_sign(self) -> float:
        axis = self._sequence()[0][0]
        return axis.sign * axis.sigma


def direction_problem(letter: str, direction) -> str | None:
    """Why ``direction`` is no supported direction of axis ``letter``, or None."""
    unit = np.zeros(3)
    unit[_UNIT[letter]] = 1.0
    if not np.array_equal(np.abs(np.asarray(direction, dtype=float)), unit):
        name = "xyz"[_UNIT[letter]]
        return (f"must be +-{name} for axis {letter} (axes at other angles are not supported "
                f"yet), got {list(direction)}")
    return None


def check_chain(tilt: RotaryAxis, turn: RotaryAxis) -> None:
    """Raise ValueError unless ``tilt`` (A along +-x or B along +-y) and ``turn`` (C along
    +-z) make a supported chain (see the module docstring)."""
    for axis, letters in ((tilt, ("A", "B")), (turn, ("C",))):
        if axis.letter not in letters:
            raise ValueError(f"axis {axis.letter}: expected {' or '.join(letters)}")
        if axis.side not in SIDES:
            raise ValueError(f"axis {axis.letter}: side must be table or head, got "
                             f"{axis.side!r}")
        problem = direction_problem(axis.letter, axis.direction)
        if problem:
            raise ValueError(f"axis {axis.letter}: direction {problem}")
    if tilt.side == "table" and turn.side == "head":
        # the C head would spin the tool about its own axis: it orients nothing
        raise ValueError(f"a C axis on the head with the {tilt.letter} axis on the table "
                         "does not orient the tool (C turns it about its own axis)")


def check_two_tilts(a: RotaryAxis, b: RotaryAxis, carrier: str) -> None:
    """Raise ValueError unless ``a`` (A along +-x) and ``b`` (B along +-y) make a two-tilt
    chain, ``carrier`` ("A" or "B") the one carrying the other."""
    for axis, letter in ((a, "A"), (b, "B")):
        if axis.letter != letter:
            raise ValueError(f"axis {axis.letter}: expected {letter}")
        if axis.side not in SIDES:
            raise ValueError(f"axis {letter}: side must be table or head, got {axis.side!r}")
        problem = direction_problem(letter, axis.direction)
        if problem:
            raise ValueError(f"axis {letter}: direction {problem}")
    if carrier not in ("A", "B"):
        raise ValueError(f"carrier must be A or B, got {carrier!r}")


def _vector(table, key: str, default=None) -> tuple[float, float, float]:
    """Three numbers from the machine file; ``default`` where the key is optional."""
    if default is not None and not table.has(key):
        return default
    values = table.get_float_list(key, min_length=3)
    if len(values) != 3:
        raise table.error(key, f"must be a list of 3 numbers (x, y, z), got {len(values)}")
    return tuple(values)


def _read_axis(table, letter: str) -> RotaryAxis:
    side = table.get_str("carried_by", choices=SIDES)
    direction = _vector(table, "direction")
    problem = direction_problem(letter, direction)
    if problem:
        raise table.error("direction", problem)
    axis = RotaryAxis(letter=letter, side=side, direction=direction,
                      point=_vector(table, "point"))
    table.finish()
    return axis


def chain_from_table(table):
    """A ``[kinematics]`` table of type ``chain``: ``tool_offset``, optional ``linear_senses``
    and ``workpiece_origin``, and one sub-table per rotary axis (``[kinematics.C]`` and
    ``[kinematics.A]`` or ``[kinematics.B]``; or ``[kinematics.A]`` and ``[kinematics.B]``, with
    ``carrier`` where both are on the same side) with ``carried_by``, ``direction``, ``point``:
    a :class:`ChainKinematics` or a :class:`TwoTiltChain`."""
    tool = table.get_float("tool_offset")
    senses = _vector(table, "linear_senses", default=(1.0, 1.0, 1.0))
    if any(v not in (1.0, -1.0) for v in senses):
        raise table.error("linear_senses", f"must be +1 or -1 each, got {list(senses)}")
    origin = _vector(table, "workpiece_origin", default=(0.0, 0.0, 0.0))
    letters = [letter for letter in ("A", "B", "C") if table.has(letter)]
    if letters == ["A", "B"]:
        return _two_tilts_from_table(table, tool, senses, origin)
    tilts = [letter for letter in letters if letter != "C"]
    if len(tilts) != 1 or "C" not in letters:
        raise table.error(None, "a chain has two rotary axes: [kinematics.C] with one tilt axis, "
                                "[kinematics.A] or [kinematics.B], or the two tilts A and B; "
                                f"got {', '.join(letters) or 'none'}")
    axes = {letter: _read_axis(table.get_table(letter), letter) for letter in (tilts[0], "C")}
    try:
        return ChainKinematics(tilt=axes[tilts[0]], turn=axes["C"], tool_offset=tool,
                               linear_senses=senses, workpiece_origin=origin)
    except ValueError as exc:
        raise table.error(None, str(exc)) from None


def _two_tilts_from_table(table, tool, senses, origin) -> TwoTiltChain:
    """The two-tilt chain: ``[kinematics.A]``, ``[kinematics.B]`` and, where both are on the
    same side, ``carrier`` = "A" or "B"."""
    a = _read_axis(table.get_table("A"), "A")
    b = _read_axis(table.get_table("B"), "B")
    if a.side == b.side:
        carrier = table.get_str("carrier", choices=("A", "B"))
    elif table.has("carrier"):
        raise table.error("carrier", f"only for two axes on the same side (A is on the {a.side},"
                                     f" B on the {b.side})")
    else:
        carrier = "B"
    return TwoTiltChain(a=a, b=b, carrier=carrier, tool_offset=tool, linear_senses=senses,
                        workpiece_origin=origin)


def chain_of(kin):
    """The chain of a kinematics object of another type (its preset), from its parameters;
    ``TypeError`` for a type that has none."""
    from .ac_trunnion import ACTrunnion
    from .xyzac_trt import XYZACTrunnion
    from .xyzbc_head_head import XYZBCHeadHead
    from .xyzbc_head_table import XYZBCHeadTable
    from .xyzbc_trt import XYZBCTrunnion

    from .xyzab_tdr import XYZABTableDualRotary

    if isinstance(kin, (ChainKinematics, TwoTiltChain)):
        return kin
    if isinstance(kin, XYZABTableDualRotary):
        # P = Rx(a) (Ry(b) (M - t ez - r) - d) + r + d: the B trunnion through r carries the
        # A table through r + d; both turn the part left-handed
        (a_min, a_max), (b_min, b_max) = kin.rotary_limits
        return TwoTiltChain(
            a=RotaryAxis("A", "table", (-1.0, 0.0, 0.0), tuple(kin._rot_point + kin._offset)),
            b=RotaryAxis("B", "table", (0.0, -1.0, 0.0), tuple(kin._rot_point)),
            carrier="B", tool_offset=kin.tool_offset,
            a_min=a_min, a_max=a_max, b_min=b_min, b_max=b_max)
    limits = dict(tilt_min=kin.tilt_limits[0], tilt_max=kin.tilt_limits[1])
    if isinstance(kin, ACTrunnion):
        # spec section 1: P = Rz(C) Rx(A) ((-X, -Y, Z) - L_ty ez) - L_ac ez
        return ChainKinematics(
            tilt=RotaryAxis("A", "table", (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
            turn=RotaryAxis("C", "table", (0.0, 0.0, -1.0), (0.0, 0.0, 0.0)),
            tool_offset=kin.L_ty, linear_senses=(-1.0, -1.0, 1.0),
            workpiece_origin=(0.0, 0.0, kin.L_ac), **limits)
    if isinstance(kin, (XYZACTrunnion, XYZBCTrunnion)):
        # P = Rz(c) (R(tilt) (tip - r - d) + d) + r: the part turned back by the table
        r = kin._rot_point
        tilt_x = isinstance(kin, XYZACTrunnion)
        d = (np.array([0.0, kin.y_offset, kin.z_offset]) if tilt_x
             else np.array([kin.x_offset, 0.0, kin.z_offset]))
        unit = np.array([1.0, 0.0, 0.0]) if tilt_x else np.array([0.0, 1.0, 0.0])
        return ChainKinematics(
            tilt=RotaryAxis("A" if tilt_x else "B", "table",
                            tuple(-kin.tilt_direction * unit), tuple(r + d)),
            turn=RotaryAxis("C", "table", (0.0, 0.0, -kin.c_direction), tuple(r)),
            tool_offset=kin.tool_offset, **limits)
    if isinstance(kin, XYZBCHeadTable):
        return ChainKinematics(
            tilt=RotaryAxis("B", "head", (0.0, kin.b_direction, 0.0),
                            (0.0, 0.0, kin.pivot_length)),
            turn=RotaryAxis("C", "table", (0.0, 0.0, kin.c_direction), tuple(kin._rot_point)),
            tool_offset=kin.tool_offset, workpiece_origin=tuple(kin._rot_point), **limits)
    if isinstance(kin, XYZBCHeadHead):
        pivot = (0.0, 0.0, kin.pivot_length)
        return ChainKinematics(
            tilt=RotaryAxis("B", "head", (0.0, kin.b_direction, 0.0), pivot),
            turn=RotaryAxis("C", "head", (0.0, 0.0, kin.c_direction), pivot),
            tool_offset=kin.tool_offset, **limits)
    raise TypeError(f"no chain preset for {type(kin).__name__}")
