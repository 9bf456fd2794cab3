"""Compiled piecewise polynomials against scipy's B-splines."""

import numpy as np
import pytest
from scipy.interpolate import BSpline, make_interp_spline

from precontour.piecewise import (FIT_OVERLAP, FIT_POINTS, bspline_pieces, evaluate,
                                  interpolating_spline, joint_control)


def _sites(rng, n, irregular=False):
    h = rng.uniform(0.05, 0.15, n - 1)
    if irregular:       # steps a hundred times shorter or longer than their neighbours
        h[rng.random(n - 1) < 0.02] *= 0.01
        h[rng.random(n - 1) < 0.02] *= 10.0
    return np.concatenate([[0.0], np.cumsum(h)])


@pytest.mark.parametrize("k", [3, 5])
def test_pieces_evaluate_like_the_bspline(k):
    rng = np.random.default_rng(k)
    x = _sites(rng, 400)
    spline = make_interp_spline(x, rng.normal(size=(x.size, 4)), k=k)
    breaks, coef = bspline_pieces(spline)
    # sorted, beyond both ends (the end pieces extend), and shuffled (bisection)
    points = np.linspace(x[0] - 0.3, x[-1] + 0.3, 5001)
    for nu in range(k + 2):
        expected = spline(points, nu)
        scale = np.abs(expected).max() + 1.0
        np.testing.assert_allclose(evaluate(breaks, coef, points, nu), expected,
                                   rtol=0, atol=1e-12 * scale)
    shuffled = rng.permutation(points)[:5000].reshape(50, 50, 2)
    np.testing.assert_allclose(evaluate(breaks, coef, shuffled, 1, slice(1, 3)),
                               spline(shuffled, 1)[..., 1:3], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("irregular", [False, True])
@pytest.mark.parametrize("k", [3, 5])
def test_interpolating_spline_is_scipys(k, irregular):
    """Solved in overlapping pieces without pivoting, the spline is scipy's one-system
    spline to round-off, across several piece seams, and interpolates the data."""
    rng = np.random.default_rng(10 * k + irregular)
    n = 3 * FIT_POINTS + FIT_OVERLAP // 2 + 17
    x = _sites(rng, n, irregular)
    y = rng.normal(size=(n, 3))
    ours = interpolating_spline(x, y, k)
    theirs = make_interp_spline(x, y, k=k)
    assert ours.k == k
    np.testing.assert_array_equal(ours.t, theirs.t)
    np.testing.assert_allclose(ours.c, theirs.c, rtol=0, atol=1e-11 * np.abs(theirs.c).max())
    np.testing.assert_allclose(ours(x), y, rtol=0, atol=1e-11)


def test_interpolating_spline_of_few_points_or_one_column():
    rng = np.random.default_rng(3)
    for n in (6, 11, 12, 40):
        x = _sites(rng, n)
        y = rng.normal(size=n)
        ours = interpolating_spline(x, y, min(5, n - 1))
        np.testing.assert_allclose(ours(x), y, atol=1e-12)
        assert ours.c.shape == (n,)
    x = _sites(rng, 30)
    assert isinstance(interpolating_spline(x, x**2, 4), BSpline)  # even degree: scipy's


def test_bad_arguments_are_refused():
    rng = np.random.default_rng(7)
    x = _sites(rng, 30)
    spline = make_interp_spline(x, rng.normal(size=(x.size, 6)), k=5)
    breaks, coef = bspline_pieces(spline)
    with pytest.raises(ValueError, match="dims must be a non-empty contiguous slice"):
        evaluate(breaks, coef, x, 0, slice(0, 6, 2))
    with pytest.raises(ValueError, match="dims must be a non-empty contiguous slice"):
        evaluate(breaks, coef, x, 0, slice(3, 3))
    with pytest.raises(ValueError, match="derivative order must be >= 0, got -1"):
        evaluate(breaks, coef, x, -1)
    other = make_interp_spline(x * 1.5, rng.normal(size=(x.size, 3)), k=5)
    with pytest.raises(ValueError, match="must share their knots and degree"):
        joint_control(spline, other)
    np.testing.assert_array_equal(joint_control(spline, spline),
                                  np.concatenate([spline.c, spline.c], axis=1))
