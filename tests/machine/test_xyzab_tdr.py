"""The A-B table dual rotary (``xyzab-tdr``, LinuxCNC's xyzab_tdr_kins) against independent
descriptions: a transcription of LinuxCNC's own forward and inverse equations (type 1, TCP;
xyzab_tdr_kins.comp) and the 4 x 4 chain of tests/machine/test_families.py. Checked: both
inverse solutions round-trip to 1e-9 mm, the path inverse stays continuous through the
singular pose B = 90 deg and keeps to the A and B travels, the orientation Jacobian equals
central differences, and the built-in machine loads with the sim's geometry."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from precontour.machine import load_machine
from precontour.machine.kinematics import XYZABTableDualRotary

from test_families import chain_of

from conftest import assert_pose_round_trip

finite = dict(allow_nan=False, allow_infinity=False)
SIM = XYZABTableDualRotary(-50.0, -50.0, -100.0, -20.0, -10.0, 0.0)
KINS = {"sim": SIM, "tool": XYZABTableDualRotary(12.0, -35.0, 80.0, 15.0, 25.0, 70.0)}
ALL = pytest.mark.parametrize("kin", list(KINS.values()), ids=list(KINS))


def linuxcnc_forward(kin, j):
    """xyzab_tdr_kins.comp's kinematicsForward, type 1, transcribed (joints in mm and degrees;
    the Cartesian position is the controlled point, the tip plus the tool length on z)."""
    xr, yr, zr = kin.x_rot_point, kin.y_rot_point, kin.z_rot_point
    dz, dt = kin.z_offset, kin.tool_offset
    sa, ca = np.sin(np.radians(j[3])), np.cos(np.radians(j[3]))
    sb, cb = np.sin(np.radians(j[4])), np.cos(np.radians(j[4]))
    px, py, pz = j[0] - xr, j[1] - yr, j[2] - zr - dt
    return np.array([cb * px + sb * pz + xr,
                     sa * sb * px + ca * py - cb * sa * pz + sa * dz + yr,
                     -ca * sb * px + sa * py + ca * cb * pz - ca * dz + zr + dz + dt])


def linuxcnc_inverse(kin, pos, a, b):
    """xyzab_tdr_kins.comp's kinematicsInverse, type 1, transcribed (A, B in degrees)."""
    xr, yr, zr = kin.x_rot_point, kin.y_rot_point, kin.z_rot_point
    dx, dz, dt = kin.x_offset, kin.z_offset, kin.tool_offset
    sa, ca = np.sin(np.radians(a)), np.cos(np.radians(a))
    sb, cb = np.sin(np.radians(b)), np.cos(np.radians(b))
    qx, qy, qz = pos[0] - xr - dx, pos[1] - yr, pos[2] - zr - dz - dt
    return np.array([cb * qx + sa * sb * qy - ca * sb * qz + cb * dx - sb * dz + xr,
                     ca * qy + sa * qz + yr,
                     sb * qx - sa * cb * qy + ca * cb * qz + sb * dx + cb * dz + zr + dt])


poses = st.tuples(st.floats(-300, 300, **finite), st.floats(-300, 300, **finite),
                  st.floats(-300, 300, **finite), st.floats(-3.1, 3.1, **finite),
                  st.floats(-3.1, 3.1, **finite))


@ALL
@settings(max_examples=200, deadline=None)
@given(q=poses)
def test_forward_and_linear_axes_are_linuxcncs(kin, q):
    q = np.array(q)
    P, O = kin.forward(q)
    joints = np.r_[q[:3], np.degrees(q[3:])]
    np.testing.assert_allclose(P + [0, 0, kin.tool_offset], linuxcnc_forward(kin, joints),
                               atol=1e-9, rtol=0)
    np.testing.assert_allclose(kin.linear_axes(P, q[3], q[4]),
                               linuxcnc_inverse(kin, P + [0, 0, kin.tool_offset],
                                                *np.degrees(q[3:])), atol=1e-9, rtol=0)
    np.testing.assert_allclose(O, [np.sin(q[4]), -np.sin(q[3]) * np.cos(q[4]),
                                   np.cos(q[3]) * np.cos(q[4])], atol=1e-15)
    P_chain, O_chain = chain_of(kin).forward(q)
    np.testing.assert_allclose(P, P_chain, atol=1e-9, rtol=0)
    np.testing.assert_allclose(O, O_chain, atol=1e-14, rtol=0)


def test_x_offset_changes_nothing():
    # it moves a point of the A axis along the A axis (LinuxCNC's forward never reads it)
    rng = np.random.default_rng(3)
    q = np.column_stack([rng.uniform(-100, 100, (200, 3)), rng.uniform(-3, 3, (200, 2))])
    P, O = SIM.forward(q)
    P2, O2 = replace(SIM, x_offset=77.0).forward(q)
    np.testing.assert_allclose(P2, P, atol=1e-12)
    np.testing.assert_array_equal(O2, O)


@ALL
@settings(max_examples=300, deadline=None)
@given(q=poses)
def test_both_solutions_round_trip(kin, q):
    q = np.array(q)
    P, O = kin.forward(q)
    if abs(np.cos(q[4])) < 1e-6:
        return  # A undefined: covered by the singularity tests
    # the pose's own solution, chosen by its B ...
    np.testing.assert_allclose(kin.inverse(P[None], O[None], c_near=np.array([q[4]]))[0, 3:],
                               np.r_[np.angle(np.exp(1j * q[3])), q[4]], atol=1e-9)
    back = kin.inverse(P[None], O[None], c_near=np.array([q[4]]))[0]
    np.testing.assert_allclose(kin.forward(back)[0], P, atol=1e-9, rtol=0)
    # ... and the other one, (A + pi, pi - B): the same tool axis and tip
    other = np.r_[0, 0, 0, q[3] + np.pi, np.pi - q[4]]
    other[:3] = kin.linear_axes(P, other[3], other[4])
    P_other, O_other = kin.forward(other)
    np.testing.assert_allclose(P_other, P, atol=1e-9, rtol=0)
    np.testing.assert_allclose(O_other, O, atol=1e-14, rtol=0)
    far = kin.inverse(P[None], O[None], c_near=np.array([np.pi - q[4]]))[0]
    np.testing.assert_allclose(np.cos(far[4] - other[4]), 1.0, atol=1e-12)
    np.testing.assert_allclose(kin.forward(far)[0], P, atol=1e-9, rtol=0)
    np.testing.assert_allclose(far[:3], other[:3], atol=1e-9, rtol=0)


@ALL
@settings(max_examples=200, deadline=None)
@given(P=st.tuples(*[st.floats(-300, 300, **finite)] * 3),
       O=st.tuples(*[st.floats(-1, 1, **finite)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_inverse_then_forward_reproduces_the_pose(kin, P, O):
    q = assert_pose_round_trip(kin, P, O)
    assert np.cos(q[4]) >= 0  # free travel: the cos B >= 0 solution


@ALL
def test_orientation_jacobian_matches_central_differences(kin):
    rng = np.random.default_rng(11)
    A, B = rng.uniform(-3, 3, 50), rng.uniform(-3, 3, 50)
    h = 1e-6
    jac = kin.orientation_jacobian(A, B)
    np.testing.assert_allclose(jac[..., 0], (kin.orientation(A + h, B)
                                             - kin.orientation(A - h, B)) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(jac[..., 1], (kin.orientation(A, B + h)
                                             - kin.orientation(A, B - h)) / (2 * h), atol=1e-9)
    chain = chain_of(kin)
    q = np.zeros((50, 5))
    q[:, 3], q[:, 4] = A, B
    for k in (0, 1):
        up, down = q.copy(), q.copy()
        up[:, 3 + k] += h
        down[:, 3 + k] -= h
        fd = np.array([(chain.forward(a)[1] - chain.forward(b)[1]) / (2 * h)
                       for a, b in zip(up, down)])
        np.testing.assert_allclose(jac[..., k], fd, atol=1e-9)
    # the A column vanishes where the tool is parallel to the A axis
    np.testing.assert_allclose(kin.orientation_jacobian(0.3, np.pi / 2)[:, 0], 0, atol=1e-15)


def _swing(offset, n=2001):
    """The tool swinging through the A axis direction (+x) in the x-z plane, ``offset`` out of
    it: B crosses 90 deg."""
    s = np.linspace(-1, 1, n)
    b = np.pi / 2 + 0.6 * s
    O = np.stack([np.sin(b), np.full_like(s, offset), np.cos(b)], axis=1)
    O /= np.linalg.norm(O, axis=1, keepdims=True)
    P = np.stack([40 * s, 10 + 0 * s, 5 * s**2], axis=1)
    return P, O


@ALL
def test_path_through_the_singularity_is_continuous(kin):
    for offset in (0.0, 1e-3):
        P, O = _swing(offset)
        q = kin.inverse(P, O)
        da, db = np.abs(np.diff(q[:, 3])), np.abs(np.diff(q[:, 4]))
        if offset == 0.0:
            # exactly through: A stays put, B sweeps on past 90 deg
            assert da.max() < 1e-12 and db.max() < 1e-3
            assert q[0, 4] < np.pi / 2 < q[-1, 4]
        else:
            # beside it: A turns by pi without a jump
            assert da.max() <= np.pi / 2 and db.max() < 0.01
            assert abs(q[-1, 3] - q[0, 3]) == pytest.approx(np.pi, abs=1e-2)
        P2, O2 = kin.forward(q)
        np.testing.assert_allclose(P2, P, atol=1e-9)
        np.testing.assert_allclose(O2, O, atol=1e-12)


def test_path_keeps_to_the_travel():
    # with B limited to +-100 deg the swing (B up to 124 deg) must turn over: the other
    # solution, B = 180 - (the swing's), within the travel all along
    limited = SIM.with_rotary_travel((-np.pi, np.pi), (-np.radians(100), np.radians(100)))
    P, O = _swing(1e-3)
    q = limited.inverse(P, O)
    assert np.radians(-100) <= q[:, 4].min() and q[:, 4].max() <= np.radians(100)
    np.testing.assert_allclose(limited.forward(q)[1], O, atol=1e-12)
    # a path far from the singularity on the cos B < 0 side when the travel asks for it
    O = np.tile([0.3, -0.2, -np.sqrt(1 - 0.13)], (100, 1))
    q_free = SIM.inverse(np.zeros((100, 3)), O)
    assert np.all(np.cos(q_free[:, 4]) > 0)
    only_back = SIM.with_rotary_travel((-np.pi, np.pi), (np.radians(100), np.radians(260)))
    q_back = only_back.inverse(np.zeros((100, 3)), O)
    assert np.all((q_back[:, 4] >= np.radians(100)) & (q_back[:, 4] <= np.radians(260)))
    np.testing.assert_allclose(only_back.forward(q_back)[1], O, atol=1e-12)
    # A in whole turns within its travel
    shifted = SIM.with_rotary_travel((np.radians(200), np.radians(500)), (None, None))
    q_a = shifted.inverse(np.zeros((100, 3)), O)
    assert np.all((q_a[:, 3] >= np.radians(200)) & (q_a[:, 3] <= np.radians(500)))


def test_a_unwraps_along_a_path():
    a = np.linspace(0, 4 * np.pi, 3000)
    O = np.stack([np.full_like(a, 0.2), -np.sin(a) * np.sqrt(0.96), np.cos(a) * np.sqrt(0.96)],
                 axis=1)
    q = SIM.inverse(np.zeros((a.size, 3)), O)
    assert np.abs(np.diff(q[:, 3])).max() < 0.01
    assert np.ptp(q[:, 3]) == pytest.approx(4 * np.pi, abs=1e-9)


def test_builtin_machine_loads_with_the_sims_geometry_and_both_travels():
    machine = load_machine("linuxcnc-xyzab-tdr")
    kin = machine.kinematics
    assert isinstance(kin, XYZABTableDualRotary)
    assert machine.axis_names == ("X", "Y", "Z", "A", "B")
    assert (kin.x_rot_point, kin.y_rot_point, kin.z_rot_point) == (-50.0, -50.0, -100.0)
    assert (kin.x_offset, kin.z_offset) == (-20.0, -10.0)
    assert kin.rotary_limits == ((machine.drive("A").p_min, machine.drive("A").p_max),
                                 (machine.drive("B").p_min, machine.drive("B").p_max))
    assert kin.tilt_limits == kin.rotary_limits[0]
