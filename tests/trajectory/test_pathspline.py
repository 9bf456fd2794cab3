import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline, PPoly

from precontour.errors import ToolPathError
from precontour.trajectory.pathspline import L_EQ, fit_path, fit_toolpath
from precontour.toolpath import ToolPath


def _orient(A, C):
    return np.stack([np.sin(A) * np.sin(C), np.sin(A) * np.cos(C), np.cos(A)], axis=-1)


def _curve(n=60):
    u = np.linspace(0.0, 1.0, n)
    P = np.stack([40 * np.cos(3 * u), 25 * np.sin(5 * u), 10 * u**2], axis=-1)
    O = _orient(0.4 + 0.5 * np.sin(2 * u), 1.5 * u)
    return P, O


def _jumps(spline):
    """Largest relative jump of derivatives 0..3 across interior breakpoints (left vs right
    polynomial piece, evaluated exactly from the piecewise-polynomial form)."""
    pp = PPoly.from_spline(spline)
    x = pp.x
    inner = np.flatnonzero(np.diff(x) > 0)
    out = []
    for nu in range(4):
        d = pp.derivative(nu) if nu else pp
        c = d.c
        # Left piece i-1 evaluated at its right end, right piece i at its left end.
        i = inner[1:]
        hl = x[i] - x[inner[:-1]]
        left = sum(c[m, inner[:-1]] * hl ** (c.shape[0] - 1 - m)
                   for m in range(c.shape[0]))
        right = c[-1, i]
        scale = np.abs(d(x[inner])).max()
        out.append(np.abs(left - right).max() / scale)
    return out


def test_tip_and_orientation_splines_are_c3_at_knots():
    P, O = _curve()
    path = fit_path(P, O)
    for spline in (path.tip_spline, path.orientation_spline):
        for j in range(3):
            component = BSpline(spline.t, spline.c[:, j], spline.k)
            assert max(_jumps(component)) < 1e-9
    # The check sees a third-derivative jump where there is one (a cubic spline).
    from scipy.interpolate import make_interp_spline
    cubic = make_interp_spline(path.s_points, P[:, 0], k=3)
    assert _jumps(cubic)[3] > 1e-3


def test_passes_through_every_point_and_orientation_is_unit():
    P, O = _curve()
    path = fit_path(P, O)
    Pi, Oi = path(path.s_points)
    np.testing.assert_allclose(Pi, P, atol=1e-9)
    np.testing.assert_allclose(Oi, O, atol=1e-12)
    s = np.linspace(0, path.length, 5001)
    np.testing.assert_allclose(np.linalg.norm(path.orientation(s), axis=1), 1.0, atol=1e-14)


def test_orientation_derivatives_match_finite_differences():
    path = fit_path(*_curve())
    s = np.linspace(1.0, path.length - 1.0, 37)
    h = 1e-3
    for nu in (1, 2, 3):
        lower = path.orientation(s, nu - 1)
        fd = (path.orientation(s + h, nu - 1) - path.orientation(s - h, nu - 1)) / (2 * h)
        scale = np.abs(lower).max() + np.abs(fd).max()
        np.testing.assert_allclose(path.orientation(s, nu), fd, atol=1e-5 * scale)
    with pytest.raises(ValueError, match="up to order 3"):
        path.orientation(s, 4)


def test_parameter_is_combined_arc_length():
    path = fit_path(*_curve(200))
    s = np.linspace(0, path.length, 20001)
    speed = np.sqrt(np.sum(path.tip(s, 1) ** 2, axis=1)
                    + L_EQ**2 * np.sum(path.orientation(s, 1) ** 2, axis=1))
    np.testing.assert_allclose(speed, 1.0, atol=2e-3)
    # Brute-force length of the fitted curve against the parameter range.
    P, O = path(s)
    ang = np.arccos(np.clip(np.sum(O[1:] * O[:-1], axis=1), -1, 1))
    brute = np.sum(np.hypot(np.linalg.norm(np.diff(P, axis=0), axis=1), L_EQ * ang))
    assert abs(brute - path.length) < 1e-4 * path.length


def test_pure_rotation_keeps_parameter_growing():
    # Line, then the tip stands still for 9 points while the tool tilts by 0.4 rad, then line.
    x = np.concatenate([np.linspace(0, 10, 11), np.full(9, 10.0), np.linspace(10, 20, 11)])
    A = np.concatenate([np.full(11, 0.3), np.linspace(0.3, 0.7, 11)[1:-1], np.full(11, 0.7)])
    P = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=-1)
    keep = np.concatenate([[True], np.diff(x) > 0]) | (np.arange(x.size) >= 10)
    P, A = P[keep], A[keep]
    path = fit_path(P, _orient(A, np.zeros_like(A)))
    assert np.all(np.diff(path.s_points) > 0)
    rotation = path.s_points[np.flatnonzero(P[:, 0] == 10)[[0, -1]]]
    assert abs(np.diff(rotation)[0] - L_EQ * 0.4) < 1e-3
    Pi, Oi = path(path.s_points)
    np.testing.assert_allclose(Pi, P, atol=1e-9)


def test_consecutive_duplicates_are_dropped():
    P, O = _curve(20)
    P2 = np.insert(P, 5, P[5], axis=0)
    O2 = np.insert(O, 5, O[5], axis=0)
    path = fit_path(P2, O2)
    assert path.point_index.tolist() == [i for i in range(21) if i != 6]
    np.testing.assert_allclose(path.length, fit_path(P, O).length, rtol=1e-12)


def test_few_points_give_one_polynomial():
    P = np.array([[0, 0, 0], [10, 0, 0.0]])
    O = _orient(np.array([0.3, 0.4]), np.zeros(2))
    path = fit_path(P, O)
    np.testing.assert_allclose(path.tip(path.length / 2), [5, 0, 0], atol=1e-12)


@pytest.mark.parametrize("P, O, match", [
    (np.zeros((1, 3)), np.array([[0, 0, 1.0]]), "at least 2 points, got 1"),
    (np.zeros((4, 3)), np.tile([0, 0, 1.0], (4, 1)), "zero-length path: all 4 points"),
    (np.zeros((3, 2)), np.zeros((3, 2)), r"shape \(M, 3\)"),
    (np.array([[0, 0, 0], [np.nan, 0, 0]]), np.tile([0, 0, 1.0], (2, 1)),
     "row 2, field 'P': P is not finite"),
    (np.array([[0, 0, 0], [1, 0, 0.0]]), np.array([[0, 0, 1.0], [0, 0, 2.0]]),
     "row 2, field 'O': orientation vector is not unit length"),
    (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]),
     np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, -1.0]]),
     "row 3, field 'O': tool orientation turns by 3.14159 rad"),
])
def test_bad_paths_raise_one_line_errors(P, O, match):
    with pytest.raises(ToolPathError, match=match) as info:
        fit_toolpath(ToolPath(P=P, O=O, source="part.nc"))
    message = str(info.value)
    assert "\n" not in message
    if P.shape[1:] == (3,) and P.shape[0] > 1:
        assert message.startswith("part.nc")


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 40))
def test_random_paths_interpolate_with_unit_orientation(seed, n):
    rng = np.random.default_rng(seed)
    P = np.cumsum(rng.uniform(0.5, 5.0, (n, 3)), axis=0)
    A = 0.2 + np.cumsum(rng.uniform(-0.1, 0.1, n))
    C = np.cumsum(rng.uniform(-0.2, 0.2, n))
    O = _orient(A, C)
    path = fit_path(P, O)
    Pi, Oi = path(path.s_points)
    np.testing.assert_allclose(Pi, P, atol=1e-6)
    np.testing.assert_allclose(Oi, O, atol=1e-6)
    s = np.linspace(0, path.length, 501)
    np.testing.assert_allclose(np.linalg.norm(path.orientation(s), axis=1), 1.0, atol=1e-12)
    assert np.all(np.diff(path.s_points) > 0)


def test_corner_points_are_sharp_turns_of_the_moves_tip_and_orientation_together():
    """A turn of 45 degrees or more between the moves into and out of a point makes it a
    corner (duplicates skipped, the corner at the first of them); a smooth curve's points
    are none, nor are the built-in paths' (at most 24.6 degrees on `paper`); a pure turn of
    the tool followed by a move of the tip is one."""
    from precontour.trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
    from precontour.trajectory.pathspline import corner_points

    up = np.tile([0.0, 0.0, 1.0], (6, 1))
    P = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 0, 0], [2, 1, 0], [2.6, 1.8, 0]],
                 dtype=float)
    assert corner_points(P, up).tolist() == [2]          # 90 degrees; then 36.9: none
    assert corner_points(P, up, angle=36.8).tolist() == [2, 4]
    theta = np.linspace(0.0, np.pi, 50)
    arc = np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
    assert corner_points(arc, np.tile([0.0, 0.0, 1.0], (50, 1))).size == 0
    for name in BUILTIN_PATHS:
        path = builtin_path(name)
        assert corner_points(path.P, path.O).size == 0, name
    # the tip stands while the tool turns by 0.2 rad, then moves 0.2 mm across
    tip = np.array([[0, 0, 0], [0, 0, 0], [0.2, 0, 0]], dtype=float)
    turn = np.array([[0, 0, 1], [np.sin(0.2), 0, np.cos(0.2)], [np.sin(0.2), 0, np.cos(0.2)]])
    assert corner_points(tip, turn).tolist() == [1]
