"""The machine families against one independent description: a kinematic chain of rotations
about lines in space (Rodrigues' formula, 4 x 4 rigid motions), the way commercial controls
describe every family -- each rotary axis with its direction, a point of its line, its sense and
whether the table or the head carries it. Every kinematics type's closed-form forward equals
its chain; the tool axis is O = -dP/dt for the tool length t on every family and dP/dZ on the
tables only; the orientation Jacobian, the path inverse and the frame the contour errors are
measured in are checked for the head families."""

from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from precontour.machine import load_machine
from precontour.machine.kinematics import (ACTrunnion, XYZABTableDualRotary, XYZACTrunnion,
                                           XYZBCHeadHead, XYZBCHeadTable, XYZBCTrunnion)

EX, EY, EZ = np.eye(3)
from conftest import assert_pose_round_trip

finite = dict(allow_nan=False, allow_infinity=False)


def _rotation(u, angle):
    """Right-handed rotation by ``angle`` about the unit vector ``u`` (Rodrigues)."""
    u = np.asarray(u, dtype=float)
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _motion(u, point, angle):
    """4 x 4 rigid motion: rotation by ``angle`` about the line through ``point`` along ``u``."""
    R = _rotation(u, angle)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(point, dtype=float) - R @ point
    return T


@dataclass(frozen=True)
class Axis:
    slot: int           # 3 (tilt) or 4 (turn) in q
    direction: tuple    # unit vector of the axis line (zero pose, machine frame)
    point: tuple        # a point of the line (head: relative to M = (X, Y, Z))
    sense: float        # physical angle = sense * q[slot]


@dataclass(frozen=True)
class Chain:
    """Head axes from the ram outwards (each carries the next), table axes from the machine
    base outwards to the workpiece, the tool tip at M - tool ez in the zero pose, and the
    workpiece frame ``frame`` (R, t: workpiece coordinates = R x + t of the last table link's
    coordinates x)."""

    head: tuple = ()
    table: tuple = ()
    tool: float = 0.0
    frame: tuple = (np.eye(3), np.zeros(3))
    linear: tuple = (1.0, 1.0, 1.0)     # X, Y, Z move the spindle nose by these times q

    def forward(self, q):
        q = np.asarray(q, dtype=float)
        M = np.asarray(self.linear) * q[:3]
        H = np.eye(4)
        for axis in self.head:
            H = H @ _motion(axis.direction, M + axis.point, axis.sense * q[axis.slot])
        tip = H[:3, :3] @ (M - self.tool * EZ) + H[:3, 3]
        axis_m = H[:3, :3] @ EZ
        T = np.eye(4)
        for axis in self.table:
            T = T @ _motion(axis.direction, axis.point, axis.sense * q[axis.slot])
        Ti = np.linalg.inv(T)
        R, t = self.frame
        return R @ (Ti[:3, :3] @ tip + Ti[:3, 3]) + t, R @ Ti[:3, :3] @ axis_m


def chain_of(kin) -> Chain:
    """The chain of a kinematics object, from its own parameters."""
    if isinstance(kin, ACTrunnion):
        # spec section 1: P = Rz(C + pi) Rx(-A) (X, Y, Z - L_ty) - L_ac ez: an A trunnion and
        # a C table through the origin, the workpiece frame turned by pi and L_ac below it
        return Chain(table=(Axis(3, EX, (0, 0, 0), 1.0), Axis(4, EZ, (0, 0, 0), -1.0)),
                     tool=kin.L_ty,
                     frame=(_rotation(EZ, np.pi), -kin.L_ac * EZ))
    if isinstance(kin, (XYZACTrunnion, XYZBCTrunnion)):
        r = np.array([kin.x_rot_point, kin.y_rot_point, kin.z_rot_point])
        tilt_x = isinstance(kin, XYZACTrunnion)
        d = (np.array([0, kin.y_offset, kin.z_offset]) if tilt_x
             else np.array([kin.x_offset, 0, kin.z_offset]))
        return Chain(table=(Axis(3, EX if tilt_x else EY, r + d, -kin.tilt_direction),
                            Axis(4, EZ, r, -kin.c_direction)), tool=kin.tool_offset)
    if isinstance(kin, XYZBCHeadTable):
        r = np.array([kin.x_rot_point, kin.y_rot_point, kin.z_rot_point])
        return Chain(head=(Axis(3, EY, (0, 0, kin.pivot_length), kin.b_direction),),
                     table=(Axis(4, EZ, r, kin.c_direction),), tool=kin.tool_offset,
                     frame=(np.eye(3), -r))
    if isinstance(kin, XYZBCHeadHead):
        pivot = (0, 0, kin.pivot_length)
        return Chain(head=(Axis(4, EZ, pivot, kin.c_direction),
                           Axis(3, EY, pivot, kin.b_direction)), tool=kin.tool_offset)
    if isinstance(kin, XYZABTableDualRotary):
        # two tilts on the table: the B trunnion on the base carries the A table, which
        # carries the part; A's line passes through the rotation point plus the offsets
        r = np.array([kin.x_rot_point, kin.y_rot_point, kin.z_rot_point])
        d = np.array([kin.x_offset, 0.0, kin.z_offset])
        return Chain(table=(Axis(4, EY, r, -1.0), Axis(3, EX, r + d, -1.0)),
                     tool=kin.tool_offset)
    raise TypeError(type(kin))


def _tool_field(kin) -> str:
    return "L_ty" if isinstance(kin, ACTrunnion) else "tool_offset"


FAMILIES = {
    "ac-trunnion": ACTrunnion(L_ac=100.0, L_ty=300.0),
    "xyzac-trt": XYZACTrunnion(12.0, -7.0, 35.0, 20.0, 10.0, 45.0, 1.0, -1.0),
    "xyzbc-trt": XYZBCTrunnion(-9.0, 4.0, -25.0, -20.0, -15.0, 60.0, -1.0, 1.0),
    "head-table iso": XYZBCHeadTable(0.0, 0.0, 0.0, 150.0, 50.0),
    "head-table -+": XYZBCHeadTable(35.0, -12.0, 7.5, 120.0, 80.0, -1.0, 1.0),
    "head-head 5axiskins": XYZBCHeadHead(250.0, 0.0),
    "head-head ++": XYZBCHeadHead(180.0, 65.0, 1.0, 1.0),
    "xyzab-tdr sim": XYZABTableDualRotary(-50.0, -50.0, -100.0, -20.0, -10.0, 0.0),
    "xyzab-tdr tool": XYZABTableDualRotary(12.0, -35.0, 80.0, 15.0, 25.0, 70.0),
}
HEADS = {name: kin for name, kin in FAMILIES.items() if name.startswith("head")}
ALL = pytest.mark.parametrize("kin", list(FAMILIES.values()), ids=list(FAMILIES))
poses = st.tuples(st.floats(-300, 300, **finite), st.floats(-300, 300, **finite),
                  st.floats(-300, 300, **finite), st.floats(-3.0, 3.0, **finite),
                  st.floats(-20, 20, **finite))


@ALL
@settings(max_examples=100, deadline=None)
@given(q=poses)
def test_forward_is_the_chains(kin, q):
    P, O = kin.forward(np.array(q))
    P_chain, O_chain = chain_of(kin).forward(q)
    np.testing.assert_allclose(P, P_chain, rtol=0, atol=1e-9)
    np.testing.assert_allclose(O, O_chain, rtol=0, atol=1e-14)


@ALL
@settings(max_examples=100, deadline=None)
@given(q=poses)
def test_tool_axis_is_where_a_shorter_tool_moves_the_tip(kin, q):
    # P is affine in the tool length t: one mm less of tool moves the tip by exactly O
    q = np.array(q)
    field = _tool_field(kin)
    P, O = kin.forward(q)
    P_short, _ = replace(kin, **{field: getattr(kin, field) - 1.0}).forward(q)
    np.testing.assert_allclose(P_short - P, O, rtol=0, atol=1e-11)


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
def test_on_a_head_the_tool_axis_is_not_dP_dZ(kin):
    q = np.array([1.0, 2.0, 3.0, 0.7, 0.4])
    P, O = kin.forward(q)
    P_up, _ = kin.forward(q + [0, 0, 1.0, 0, 0])
    np.testing.assert_allclose(np.linalg.norm(P_up - P), 1.0)   # Z moves the tip by 1 mm ...
    assert np.linalg.norm(P_up - P - O) > 0.5                  # ... but not along the tool


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
@settings(max_examples=200, deadline=None)
@given(P=st.tuples(*[st.floats(-300, 300, **finite)] * 3),
       O=st.tuples(*[st.floats(-1, 1, **finite)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_head_inverse_then_forward_reproduces_the_pose(kin, P, O):
    assert_pose_round_trip(kin, P, O)


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
@settings(max_examples=200, deadline=None)
@given(q=poses)
def test_head_forward_then_inverse_returns_the_axes(kin, q):
    # both solutions: the axes themselves, and the other branch (tilt negated, C + pi), which
    # points the tool the same way and puts the tip at the same point
    q = np.array(q)
    P, O = kin.forward(q)
    if abs(np.sin(q[3])) > 1e-6:
        np.testing.assert_allclose(kin.inverse(P, O, c_near=np.array(q[4])), q, atol=1e-9)
        other = q + [0, 0, 0, 0, np.pi]
        other[3] = -q[3]
        other[:3] = kin.linear_axes(P, other[3], other[4])
        P_other, O_other = kin.forward(other)
        np.testing.assert_allclose(P_other, P, atol=1e-9)
        np.testing.assert_allclose(O_other, O, atol=1e-14)
        np.testing.assert_allclose(kin.inverse(P, O, c_near=np.array(other[4])), other,
                                   atol=1e-9)


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
def test_head_path_through_the_pole_is_continuous(kin):
    # the tool swings through vertical (parallel to the C axis) in the x-z plane: B crosses 0
    # and C stays put; beside the pole C turns by pi without a jump
    s = np.linspace(-1, 1, 2001)
    for offset in (0.0, 1e-3):
        O = np.stack([np.sin(0.6 * s), np.full_like(s, offset), np.cos(0.6 * s)], axis=1)
        O /= np.linalg.norm(O, axis=1, keepdims=True)
        P = np.stack([40 * s, 10 + 0 * s, 5 * s**2], axis=1)
        q = kin.inverse(P, O)
        dc = np.abs(np.diff(q[:, 4]))
        if offset == 0.0:
            assert dc.max() < 1e-12 and q[0, 3] * q[-1, 3] < 0
        else:
            assert dc.max() <= np.pi / 2 and abs(q[-1, 4] - q[0, 4]) == pytest.approx(np.pi,
                                                                                     abs=1e-2)
        P2, O2 = kin.forward(q)
        np.testing.assert_allclose(P2, P, atol=1e-9)
        np.testing.assert_allclose(O2, O, atol=1e-12)


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
def test_head_c_unwraps_over_several_turns(kin):
    c = np.linspace(0, 6 * np.pi, 5000)
    O = np.stack([0.5 * np.cos(c), 0.5 * np.sin(c), np.full_like(c, np.sqrt(0.75))], axis=1)
    q = kin.inverse(np.zeros((c.size, 3)), O)
    assert np.abs(np.diff(q[:, 4])).max() < 0.01
    assert np.ptp(q[:, 4]) == pytest.approx(6 * np.pi, abs=1e-9)
    np.testing.assert_allclose(kin.forward(q)[1], O, atol=1e-12)


@pytest.mark.parametrize("kin", list(HEADS.values()), ids=list(HEADS))
def test_head_orientation_jacobian_matches_central_differences(kin):
    rng = np.random.default_rng(7)
    B, C = rng.uniform(-3, 3, 50), rng.uniform(-7, 7, 50)
    h = 1e-6
    jac = kin.orientation_jacobian(B, C)
    np.testing.assert_allclose(jac[..., 0], (kin.orientation(B + h, C)
                                             - kin.orientation(B - h, C)) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(jac[..., 1], (kin.orientation(B, C + h)
                                             - kin.orientation(B, C - h)) / (2 * h), atol=1e-9)
    # and against the chain's forward, the independent description
    q = np.zeros((50, 5))
    q[:, 3], q[:, 4] = B, C
    chain = chain_of(kin)
    for k in (0, 1):
        up, down = q.copy(), q.copy()
        up[:, 3 + k] += h
        down[:, 3 + k] -= h
        fd = np.array([(chain.forward(a)[1] - chain.forward(b)[1]) / (2 * h)
                       for a, b in zip(up, down)])
        np.testing.assert_allclose(jac[..., k], fd, atol=1e-9)


def test_workpiece_frame_turns_with_the_table_not_with_the_head():
    # A C error of d rad at a tilt b: on the head-table machine the part turns under a still
    # tool, so a tip r mm from the C axis moves r d (whatever the tool); on the head-head
    # machine the head turns about the C axis through the pivot, so the tip, (p + t) sin b
    # from that axis, moves (p + t) sin b d. The tool axis turns by d sin b relative to the
    # part on both.
    d, b = 1e-4, 0.6
    table = XYZBCHeadTable(0.0, 0.0, 0.0, 150.0, 50.0)
    head = XYZBCHeadHead(250.0, 0.0)
    for kin, moved in ((table, None), (head, (250.0 + 0.0) * np.sin(b) * d)):
        P = np.array([40.0, 30.0, 5.0])
        O = np.array([np.sin(b), 0.0, np.cos(b)])
        q = kin.inverse(P, O)
        q_err = q + [0, 0, 0, 0, d]
        P2, O2 = kin.forward(q_err)
        angle = np.arctan2(np.linalg.norm(np.cross(O, O2)), O @ O2)
        assert angle == pytest.approx(d * np.sin(b), rel=1e-6)
        if moved is None:
            moved = np.hypot(P[0], P[1]) * d    # the C axis passes through the workpiece origin
        assert np.linalg.norm(P2 - P) == pytest.approx(moved, rel=1e-3)


@pytest.mark.parametrize("name, kind, cls", [("head-table-bc", "xyzbc-head-table",
                                              XYZBCHeadTable),
                                             ("linuxcnc-bridgemill", "xyzbc-head-head",
                                              XYZBCHeadHead)])
def test_builtin_head_machines_load_with_their_tilt_travel(name, kind, cls):
    machine = load_machine(name)
    assert isinstance(machine.kinematics, cls)
    assert machine.axis_names == ("X", "Y", "Z", "B", "C")
    low, high = machine.kinematics.tilt_limits
    assert (low, high) == (machine.drive("B").p_min, machine.drive("B").p_max)
    assert low < 0 < high
