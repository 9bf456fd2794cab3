import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from precontour.errors import InputError
from precontour.machine.kinematics import ACTrunnion, normalize_orientations
from precontour.machine.kinematics.ac_trunnion import POLE_TOLERANCE

KIN = ACTrunnion(L_ac=100.0, L_ty=300.0)
KIN_POSITIVE_A = ACTrunnion(L_ac=100.0, L_ty=300.0, a_min=0.0, a_max=2.0)

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
    O = np.array([np.sin(A) * np.sin(C), np.sin(A) * np.cos(C), np.cos(A)])
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
    O = np.stack([np.sin(angle) * np.sin(c), np.sin(angle) * np.cos(c), np.cos(angle)], axis=1)
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
    O = np.stack([0.5 * np.sin(c), 0.5 * np.cos(c), np.full_like(c, np.sqrt(0.75))], axis=1)
    q = KIN.inverse(np.zeros((c.size, 3)), O)
    np.testing.assert_allclose(q[:, 4], c, atol=1e-12)
    np.testing.assert_allclose(q[:, 3], np.arccos(np.sqrt(0.75)), atol=1e-12)


def test_c_near_scalar_picks_the_period():
    O = np.array([[0.0, 0.5, np.sqrt(0.75)]] * 3)
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
