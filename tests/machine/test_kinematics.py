import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from precontour.errors import InputError
from precontour.machine.kinematics import (ACTrunnion, XYZACTrunnion, XYZBCHeadHead,
                                           XYZBCHeadTable, XYZBCTrunnion,
                                           normalize_orientations)
from precontour.machine.kinematics.ac_trunnion import POLE_TOLERANCE

KIN = ACTrunnion(L_ac=100.0, L_ty=300.0)
KIN_POSITIVE_A = ACTrunnion(L_ac=100.0, L_ty=300.0, a_min=0.0, a_max=2.0)

from conftest import assert_pose_round_trip

finite = dict(allow_nan=False, allow_infinity=False)
axes = st.tuples(st.floats(-500, 500, **finite), st.floats(-500, 500, **finite),
                 st.floats(-200, 600, **finite), st.floats(0.01, 3.1, **finite),
                 st.floats(-20, 20, **finite))


@settings(max_examples=300, deadline=None)
@given(axes)
def test_axes_to_tool_and_back(q):
    q = np.array(q)
    P, O = KIN.forward(q)
    np.testing.assert_allclose(np.linalg.norm(O), 1.0, atol=1e-15)
    q2 = KIN.inverse(P, O, c_near=np.array(q[4]))
    np.testing.assert_allclose(q2, q, atol=1e-9, rtol=0)


@settings(max_examples=300, deadline=None)
@example(P=(0.0, 0.0, 0.0), O=(0.0, -1.9e-13, 0.25))   # just off the pole (found by hypothesis)
@given(st.tuples(st.floats(-300, 300, **finite), st.floats(-300, 300, **finite),
                 st.floats(-300, 300, **finite)),
       st.tuples(st.floats(-1, 1, **finite), st.floats(-1, 1, **finite),
                 st.floats(-1, 1, **finite)).filter(lambda v: 0.1 < np.linalg.norm(v)))
def test_tool_to_axes_and_back(P, O):
    P = np.array(P)
    O = np.array(O) / np.linalg.norm(O)
    for kin in (KIN, KIN_POSITIVE_A):
        q = kin.inverse(P, O)
        P2, O2 = kin.forward(q)
        np.testing.assert_allclose(P2, P, atol=1e-9, rtol=0)
        # within POLE_TOLERANCE of the pole C is undefined and taken from its neighbours (here
        # 0): the orientation is then reproduced to 2 POLE_TOLERANCE, elsewhere to round-off
        np.testing.assert_allclose(O2, O, atol=2 * POLE_TOLERANCE + 1e-15, rtol=0)


def test_inverse_matches_spec_formulas_on_a_known_point():
    # A = 0.5, C = 0.3, hand-evaluated spec section 1 formulas
    A, C = 0.5, 0.3
    O = np.array([np.sin(A) * np.sin(C), -np.sin(A) * np.cos(C), np.cos(A)])
    P = np.array([10.0, -20.0, 30.0])
    X = -np.cos(C) * 10 - np.sin(C) * -20
    Y = np.cos(A) * np.sin(C) * 10 - np.cos(A) * np.cos(C) * -20 - np.sin(A) * 30 - np.sin(A) * 100
    Z = np.sin(A) * np.sin(C) * 10 - np.sin(A) * np.cos(C) * -20 + np.cos(A) * 30 + np.cos(A) * 100 + 300
    np.testing.assert_allclose(KIN.inverse(P, O), [X, Y, Z, A, C], atol=1e-12)


def _path_through_pole(n=2001, offset=0.0):
    # orientation swings in the x-z plane (plus an optional sideways offset) through vertical
    s = np.linspace(-1, 1, n)
    theta = 0.6 * s
    O = np.stack([np.sin(theta), np.full(n, offset), np.cos(theta)], axis=1)
    O /= np.linalg.norm(O, axis=1, keepdims=True)
    P = np.stack([40 * s, 10 + 0 * s, 5 * s**2], axis=1)
    return P, O


@pytest.mark.parametrize("offset", [0.0, 1e-13, 1e-6, 1e-3])
@pytest.mark.parametrize("kin", [KIN, KIN_POSITIVE_A], ids=["A both ways", "A >= 0"])
def test_path_through_or_near_the_pole_is_continuous(offset, kin):
    P, O = _path_through_pole(offset=offset)
    q = kin.inverse(P, O)
    assert np.all(np.isfinite(q))
    # Exactly through the pole, a tilting A axis crosses zero and C stays put. Passing beside
    # the pole, C must really turn by pi (both branches need it): fast, but never a jump of more
    # than pi/2 between samples and never a 2 pi wrap.
    dc = np.abs(np.diff(q[:, 4]))
    if kin.negative_a_allowed and offset <= 1e-13:
        assert dc.max() < 1e-2
        assert q[0, 3] * q[-1, 3] < 0
    else:
        assert dc.max() <= np.pi / 2 + 1e-12
        assert abs(q[-1, 4] - q[0, 4]) == pytest.approx(np.pi, abs=1e-2)
    P2, O2 = kin.forward(q)
    np.testing.assert_allclose(P2, P, atol=1e-9)
    np.testing.assert_allclose(O2, O, atol=2e-10)


def test_exactly_vertical_stretch_interpolates_c():
    n = 300
    angle = np.concatenate([np.linspace(0.5, 0, 100), np.zeros(100), np.linspace(0, 0.5, 100)])
    c = np.concatenate([np.full(100, 0.2), np.zeros(100), np.full(100, 0.8)])
    O = np.stack([np.sin(angle) * np.sin(c), -np.sin(angle) * np.cos(c), np.cos(angle)], axis=1)
    P = np.zeros((n, 3))
    q = KIN_POSITIVE_A.inverse(P, O)
    C = q[:, 4]
    assert np.all(np.isfinite(C))
    assert np.all(np.diff(C[99:201]) >= -1e-15)      # monotone blend 0.2 -> 0.8 over the pole
    np.testing.assert_allclose(C[:99], 0.2, atol=1e-12)
    np.testing.assert_allclose(C[201:], 0.8, atol=1e-12)
    _, O2 = KIN_POSITIVE_A.forward(q)
    np.testing.assert_allclose(O2, O, atol=1e-12)


def test_c_unwraps_over_several_turns():
    c = np.linspace(0, 6 * np.pi, 5000)
    O = np.stack([0.5 * np.sin(c), -0.5 * np.cos(c), np.full_like(c, np.sqrt(0.75))], axis=1)
    q = KIN.inverse(np.zeros((c.size, 3)), O)
    np.testing.assert_allclose(q[:, 4], c, atol=1e-12)
    np.testing.assert_allclose(q[:, 3], np.arccos(np.sqrt(0.75)), atol=1e-12)


def test_c_near_scalar_picks_the_period():
    O = np.array([[0.0, -0.5, np.sqrt(0.75)]] * 3)
    q = KIN_POSITIVE_A.inverse(np.zeros((3, 3)), O, c_near=4 * np.pi + 0.1)
    np.testing.assert_allclose(q[:, 4], 4 * np.pi)


def test_non_unit_orientation(caplog):
    O = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8 * (1 + 5e-7)], [0.0, 0.0, 1.5]])
    with pytest.raises(InputError, match=r"path.csv, row 3, field 'O': .*not unit length"):
        normalize_orientations(O, source="path.csv")
    out = normalize_orientations(O[:2], source="path.csv")
    assert "path.csv: normalized 1 orientation vectors" in caplog.text
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-15)
    with pytest.raises(InputError, match="row 1"):
        normalize_orientations(np.array([[np.nan, 0, 1.0]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        normalize_orientations(np.array([[0.0, 0.0, 1.0 + 1e-15]]))   # round-off: silent


# --------------------------------------------------------------------------- every type

S3 = np.sqrt(3.0) / 2.0
#: LinuxCNC's simulator geometries (xyzac-trt.ini / xyzbc-trt.ini HAL settings), default
#: directions (conventional-directions 0), plus variants with other offsets and signs.
XYZAC_SIM = XYZACTrunnion(x_rot_point=0.0, y_rot_point=0.0, z_rot_point=0.0, y_offset=20.0,
                          z_offset=10.0, tool_offset=0.0, a_direction=-1.0, c_direction=-1.0)
XYZBC_SIM = XYZBCTrunnion(x_rot_point=0.0, y_rot_point=0.0, z_rot_point=0.0, x_offset=-20.0,
                          z_offset=-15.0, tool_offset=0.0, b_direction=-1.0, c_direction=-1.0)
ALL_KINEMATICS = {
    "ac-trunnion": KIN,
    "ac-trunnion A>=0": KIN_POSITIVE_A,
    "xyzac-trt sim": XYZAC_SIM,
    "xyzac-trt offsets +-": XYZACTrunnion(12.0, -7.0, 35.0, 20.0, 10.0, 45.0, 1.0, -1.0),
    "xyzac-trt limited": replace(XYZAC_SIM, a_min=np.radians(-100), a_max=np.radians(50)),
    "xyzbc-trt sim": XYZBC_SIM,
    "xyzbc-trt offsets -+": XYZBCTrunnion(-9.0, 4.0, -25.0, -20.0, -15.0, 60.0, -1.0, 1.0),
    "xyzbc-trt limited": replace(XYZBC_SIM, b_min=np.radians(-100), b_max=np.radians(50)),
}
#: The head families: a tilting B head over a C table, and LinuxCNC 5axiskins's B-C fork head.
HEAD_TABLE = XYZBCHeadTable(x_rot_point=0.0, y_rot_point=0.0, z_rot_point=0.0,
                            pivot_length=150.0, tool_offset=50.0)
BRIDGEMILL = XYZBCHeadHead(pivot_length=250.0, tool_offset=0.0)
HEAD_KINEMATICS = {
    "head-table iso": HEAD_TABLE,
    "head-table offsets -+": XYZBCHeadTable(35.0, -12.0, 7.5, 120.0, 80.0, -1.0, 1.0),
    "head-table limited": replace(HEAD_TABLE, b_min=np.radians(-110), b_max=np.radians(30)),
    "head-head 5axiskins": BRIDGEMILL,
    "head-head tool ++": XYZBCHeadHead(180.0, 65.0, 1.0, 1.0),
    "head-head limited": replace(BRIDGEMILL, b_min=np.radians(-120), b_max=np.radians(40)),
}
TABLE_KINEMATICS = dict(ALL_KINEMATICS)
ALL_KINEMATICS.update(HEAD_KINEMATICS)
KINEMATICS_PARAMS = pytest.mark.parametrize("kin", list(ALL_KINEMATICS.values()),
                                            ids=list(ALL_KINEMATICS))


@pytest.mark.parametrize("kin, q_deg, P, O", [
    # LinuxCNC trtfuncs.c xyzacKinematicsForward evaluated by hand (con = -1, dy 20, dz 10):
    # A = C = 0: every rotation is the identity, the tip is where X, Y, Z put it
    (XYZAC_SIM, (1, 2, 3, 0, 0), (1, 2, 3), (0, 0, 1)),
    # A = -30 deg: y = cA (Y - dy) - con sA (Z - dz) + dy = -17.3205 + 5 + 20;
    # z = con sA (Y - dy) + cA (Z - dz) + dz = -10 - 8.6603 + 10
    (XYZAC_SIM, (0, 0, 0, -30, 0), (0, 20 - 20 * S3 + 5, -10 * S3), (0, -0.5, S3)),
    # A = -90, C = 90 deg: x = -sC (Z - dz) + sC dy = -20 + 20; y = con sC X = -10;
    # z = con sA (Y - dy) + dz = -15 + 10
    (XYZAC_SIM, (10, 5, 30, -90, 90), (0, -10, -5), (-1, 0, 0)),
    # conventional directions, tool offset 5 (LinuxCNC's dz = 10 + 5): its z = -20 + 15 = -5
    # is the controlled point, the tip is 5 below: -10; y = -(Z - dz) + dy = 15 + 20
    (XYZACTrunnion(0, 0, 0, 20, 10, 5, 1, 1), (0, 0, 0, 90, 0), (0, 35, -10), (0, -1, 0)),
    # xyzbcKinematicsForward by hand (con = -1, dx -20, dz -15), B = -30 deg:
    # x = cB (X - dx) + con sB (Z - dz) + dx = 17.3205 + 7.5 - 20;
    # z = -con sB (X - dx) + cB (Z - dz) + dz = -10 + 12.9904 - 15
    (XYZBC_SIM, (0, 0, 0, -30, 0), (20 * S3 + 7.5 - 20, 0, -10 + 15 * S3 - 15), (0.5, 0, S3)),
    # B = -90, C = 90 deg: x = -con sC Y = 5; y = sC sB (Z - dz) + con sC dx = -45 + 20;
    # z = -con sB (X - dx) + dz = -30 - 15
    (XYZBC_SIM, (10, 5, 30, -90, 90), (5, -25, -45), (0, -1, 0)),
    # spec section 1 (zhang2013, L_ac 100, L_ty 300) at A = 90 deg, C = 0:
    # Px = -X; Py = -Z + L_ty; Pz = -Y - L_ac
    (KIN, (1, 2, 3, 90, 0), (-1, 297, -102), (0, -1, 0)),
])
def test_forward_matches_published_equations_by_hand(kin, q_deg, P, O):
    q = np.array(q_deg, dtype=float)
    q[3:] = np.radians(q[3:])
    P_kin, O_kin = kin.forward(q)
    np.testing.assert_allclose(P_kin, P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(O_kin, O, rtol=0, atol=1e-15)
    np.testing.assert_allclose(kin.linear_axes(P, q[3], q[4]), q[:3], rtol=0, atol=1e-12)


poses = st.tuples(st.floats(-300, 300, **finite), st.floats(-300, 300, **finite),
                  st.floats(-300, 300, **finite), st.floats(-3.0, 3.0, **finite),
                  st.floats(-20, 20, **finite))


@pytest.mark.parametrize("kin", list(TABLE_KINEMATICS.values()), ids=list(TABLE_KINEMATICS))
@settings(max_examples=150, deadline=None)
@given(q=poses)
def test_tool_axis_is_dP_dZ(kin, q):
    # O is the direction in which the spindle axis Z moves the tip (spec section 1); P is
    # affine in Z, so a unit step of Z moves the tip by exactly O. (On a head Z moves the tip
    # along z whatever the tilt: tests/machine/test_families.py checks O = -dP/dt there.)
    q = np.array(q)
    P, O = kin.forward(q)
    P_up, _ = kin.forward(q + [0, 0, 1.0, 0, 0])
    np.testing.assert_allclose(P_up - P, O, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(O), 1.0, atol=1e-15)
    np.testing.assert_allclose(kin.orientation(q), O, rtol=0, atol=0)
    np.testing.assert_allclose(kin.orientation(q[3], q[4]), O, rtol=0, atol=0)


@KINEMATICS_PARAMS
@settings(max_examples=150, deadline=None)
@given(q=poses)
def test_linear_axes_and_inverse_undo_forward(kin, q):
    q = np.array(q)
    P, O = kin.forward(q)
    np.testing.assert_allclose(kin.linear_axes(P, q[3], q[4]), q[:3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(kin.linear_axes(P, q[3:]), q[:3], rtol=0, atol=1e-9)
    lower, upper = kin.tilt_limits
    inside = (lower is None or lower <= q[3]) and (upper is None or q[3] <= upper)
    if inside and abs(np.sin(q[3])) > 1e-6:   # off the pole, (A, C) is unique up to branch
        np.testing.assert_allclose(kin.inverse(P, O, c_near=np.array(q[4])), q, atol=1e-8)


@KINEMATICS_PARAMS
@settings(max_examples=150, deadline=None)
@given(P=st.tuples(*[st.floats(-300, 300, **finite)] * 3),
       O=st.tuples(*[st.floats(-1, 1, **finite)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_inverse_then_forward_reproduces_the_pose(kin, P, O):
    q = assert_pose_round_trip(kin, P, O)
    O = np.array(O) / np.linalg.norm(O)
    lower, upper = kin.tilt_limits
    if lower is not None and O[2] > np.cos(min(-lower, upper)):  # inside the travel both ways
        assert lower <= q[3] <= upper


@KINEMATICS_PARAMS
def test_orientation_jacobian_matches_central_differences(kin):
    rng = np.random.default_rng(5)
    A, C = rng.uniform(-3, 3, 50), rng.uniform(-7, 7, 50)
    h = 1e-6
    jac = kin.orientation_jacobian(A, C)
    d_a = (kin.orientation(A + h, C) - kin.orientation(A - h, C)) / (2 * h)
    d_c = (kin.orientation(A, C + h) - kin.orientation(A, C - h)) / (2 * h)
    np.testing.assert_allclose(jac[..., 0], d_a, atol=1e-9)
    np.testing.assert_allclose(jac[..., 1], d_c, atol=1e-9)


@pytest.mark.parametrize("kin", [XYZAC_SIM, XYZBC_SIM, HEAD_TABLE, BRIDGEMILL],
                         ids=["xyzac", "xyzbc", "head-table", "head-head"])
def test_tilt_sign_keeps_the_path_inside_the_travel(kin):
    limited = kin.with_tilt_limits(np.radians(-100), np.radians(50))
    assert limited.tilt_limits == (np.radians(-100), np.radians(50))
    # a cone of tool axes 60 deg from vertical: only the negative commanded tilt fits the
    # -100..50 deg travel; with no travel limits the positive one is taken
    c = np.linspace(0, 2 * np.pi, 200)
    tilt = np.radians(60)
    O = np.stack([np.sin(tilt) * np.cos(c), np.sin(tilt) * np.sin(c), np.full_like(c, 0.5)], 1)
    P = np.zeros_like(O)
    np.testing.assert_allclose(limited.inverse(P, O)[:, 3], -tilt, atol=1e-12)
    np.testing.assert_allclose(kin.inverse(P, O)[:, 3], tilt, atol=1e-12)
    # a swing exactly through the pole from 60 deg on one side to 60 deg on the other: the
    # continuous branch would reach +60 deg, so C turns by pi at the pole instead and the
    # tilt stays negative
    theta = np.radians(60) * np.linspace(-1, 1, 201)
    O = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
    q = limited.inverse(np.zeros_like(O), O)
    assert np.all(q[:, 3] <= 1e-12) and q[:, 3].min() == pytest.approx(-np.radians(60))
    assert abs(q[-1, 4] - q[0, 4]) == pytest.approx(np.pi, abs=1e-12)
    np.testing.assert_allclose(limited.forward(q)[1], O, atol=1e-12)
    assert np.ptp(kin.inverse(np.zeros_like(O), O)[:, 4]) < 1e-12   # free: tilt crosses zero


def test_only_negative_tilt_allowed():
    kin = XYZAC_SIM.with_tilt_limits(np.radians(-100), 0.0)
    c = np.linspace(0, 6 * np.pi, 500)
    O = np.stack([0.5 * np.sin(c), 0.5 * np.cos(c), np.full_like(c, S3)], axis=1)
    q = kin.inverse(np.zeros_like(O), O)
    np.testing.assert_allclose(q[:, 3], -np.radians(30), atol=1e-12)
    assert np.abs(np.diff(q[:, 4])).max() < 0.05            # unwrapped over three turns
    np.testing.assert_allclose(kin.forward(q)[1], O, atol=1e-12)


def test_rotary_pair_rejects_other_shapes():
    with pytest.raises(ValueError, match="shape"):
        XYZAC_SIM.orientation(np.zeros((4, 3)))


@settings(max_examples=200, deadline=None)
@given(steps=st.lists(st.floats(-7.0, 7.0), min_size=1, max_size=60),
       start=st.floats(-4.0, 4.0), half_turns=st.booleans(), wrap=st.booleans())
@example(steps=[np.pi / 2, -np.pi / 2, np.pi, -np.pi], start=0.0, half_turns=True, wrap=False)
def test_path_unwrap_is_numpys_to_the_bit(steps, start, half_turns, wrap):
    """The compiled unwrap of the path inverse gives numpy.unwrap's every bit, steps of
    exactly half a period included (numpy's tie rule)."""
    from precontour.machine.kinematics._trunnion import _unwrap
    c = start + np.cumsum([0.0] + steps)
    if wrap:
        c = np.arctan2(np.sin(c), np.cos(c))
    period = np.pi if half_turns else 2.0 * np.pi
    np.testing.assert_array_equal(_unwrap(c, period), np.unwrap(c, period=period))
