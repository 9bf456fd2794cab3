import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from precontour.errors import InputError
from precontour.prediction.splinefit import fit_axes, fit_min_jerk

from conftest import analytic_axis


def _dense_min_jerk(t_knots, x_knots):
    """Independent reference: monomial coefficients per segment, the spec's jerk integral
    (section 3) as the Hessian, all constraints explicit, one dense KKT solve."""
    n = t_knots.size - 1
    h = np.diff(t_knots)
    nv = 6 * n
    H = np.zeros((nv, nv))
    for i in range(n):
        b = slice(6 * i, 6 * i + 6)   # coefficients b0..b5 ascending
        hi = h[i]
        Q = np.zeros((6, 6))
        # 720 b5^2 h^5 + 720 b5 b4 h^4 + (240 b5 b3 + 192 b4^2) h^3 + 144 b4 b3 h^2 + 36 b3^2 h
        Q[5, 5] = 720 * hi**5
        Q[5, 4] = Q[4, 5] = 360 * hi**4
        Q[5, 3] = Q[3, 5] = 120 * hi**3
        Q[4, 4] = 192 * hi**3
        Q[4, 3] = Q[3, 4] = 72 * hi**2
        Q[3, 3] = 36 * hi
        H[b, b] = 2 * Q
    rows, rhs = [], []

    def deriv_row(i, tau, k):
        r = np.zeros(nv)
        for p in range(k, 6):
            r[6 * i + p] = np.prod(range(p - k + 1, p + 1)) * tau ** (p - k)
        return r
    for i in range(n):
        rows += [deriv_row(i, 0.0, 0), deriv_row(i, h[i], 0)]
        rhs += [x_knots[i], x_knots[i + 1]]
    for i in range(n - 1):
        for k in (1, 2, 3):
            rows.append(deriv_row(i, h[i], k) - deriv_row(i + 1, 0.0, k))
            rhs.append(0.0)
    for k in (1, 2, 3):
        rows += [deriv_row(0, 0.0, k), deriv_row(n - 1, h[-1], k)]
        rhs += [0.0, 0.0]
    L = np.array(rows)
    kkt = np.block([[H, L.T], [L, np.zeros((L.shape[0], L.shape[0]))]])
    sol = np.linalg.lstsq(kkt, np.concatenate([np.zeros(nv), rhs]), rcond=None)[0]
    return sol[:nv].reshape(n, 6)


def _smooth_samples(n=2501, duration=2.5):
    t = np.linspace(0, duration, n)
    return t, analytic_axis(t, duration, 10.0, 60.0, 3.0, 2.3)[0]


def test_matches_dense_spec_formulation():
    rng = np.random.default_rng(1)
    # segment lengths 0.5-2.5 (time unit = a typical segment) keep the dense monomial KKT
    # system well conditioned enough to serve as a reference
    t_knots = np.cumsum(np.concatenate([[0.0], rng.uniform(0.5, 2.5, 12)]))
    x_knots = np.cumsum(rng.normal(0, 1, 13))
    # make the knots the whole sample set so the fit cannot add any
    fit = fit_min_jerk(t_knots, x_knots, tol=1e9)
    assert fit.n_knots == 4                # initial fit: 3 segments through 4 of the samples
    from precontour.prediction.splinefit import _solve_min_jerk, _to_ppoly
    spline = _to_ppoly(_solve_min_jerk(t_knots, x_knots), t_knots)
    dense = _dense_min_jerk(t_knots, x_knots)
    ours = spline.c[::-1].T
    scale = np.abs(dense).max(axis=0)
    assert np.all(np.abs(ours - dense) <= 1e-7 * scale)


def test_jerk_integral_matches_spec_formula():
    t, x = _smooth_samples()
    fit = fit_min_jerk(t, x, 1e-3)
    jerk = fit.spline.derivative(3)
    numeric = sum(quad(lambda s: jerk(s) ** 2, a, b, epsabs=0, epsrel=1e-12)[0]
                  for a, b in zip(fit.spline.x[:-1], fit.spline.x[1:]))
    c = fit.spline.c
    h = np.diff(fit.spline.x)
    b5, b4, b3 = c[0], c[1], c[2]
    formula = np.sum(720 * b5**2 * h**5 + 720 * b5 * b4 * h**4 + (240 * b5 * b3 + 192 * b4**2) * h**3
                     + 144 * b4 * b3 * h**2 + 36 * b3**2 * h)
    assert numeric == pytest.approx(formula, rel=1e-9)


def _check_c3_and_rest(spline, rtol=1e-9):
    x = spline.x
    h = np.diff(x)
    for nu in (0, 1, 2, 3):
        d = spline.derivative(nu) if nu else spline
        left = np.array([np.polyval(d.c[:, i], h[i]) for i in range(h.size - 1)])
        right = d.c[-1, 1:]
        scale = np.abs(d(np.linspace(x[0], x[-1], 4001))).max()
        assert np.abs(left - right).max() <= rtol * scale, nu
        if nu:
            assert abs(d(x[0])) <= rtol * scale and abs(d(x[-1])) <= 1e-8 * scale, nu


@pytest.mark.parametrize("tol", [1e-3, 1e-5])
def test_fit_within_tolerance_exact_at_knots_c3(tol):
    t, x = _smooth_samples()
    x = x + np.where(t > 1.2, 0.5 * (t - 1.2) ** 2, 0.0) * 0  # keep smooth
    fit = fit_min_jerk(t, x, tol)
    dev = np.abs(fit(t) - x)
    assert dev.max() <= tol
    assert fit.max_deviation == pytest.approx(dev.max(), rel=1e-6, abs=1e-15)
    np.testing.assert_allclose(fit(t[fit.knot_index]), x[fit.knot_index], atol=1e-9 * np.abs(x).max())
    _check_c3_and_rest(fit.spline)


def test_knots_added_per_stretch_keep_rounds_few():
    # a long trajectory with many local features: knots are added at every out-of-tolerance
    # stretch at once, so the number of rounds stays small while the knot count grows
    t = np.arange(0, 60.0, 1e-3)
    s = t / t[-1]
    chirp = np.sin(2 * np.pi * (1 + 4 * s) * t) * (s * (1 - s)) ** 4 * 256
    x = 100 * (35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7) + 2 * chirp
    fit = fit_min_jerk(t, x, 1e-4)
    assert np.abs(fit(t) - x).max() <= 1e-4
    assert fit.rounds <= 15
    assert fit.n_knots > 60000 // 50


@settings(max_examples=30, deadline=None)
@given(st.integers(4, 400), st.floats(1e-4, 1e-1), st.integers(0, 2**32 - 1))
def test_random_walks_always_fit(n, tol, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    x = np.cumsum(rng.normal(0, 0.05, n))
    fit = fit_min_jerk(t, x, tol)
    assert np.abs(fit(t) - x).max() <= tol
    assert fit(t[0], 1) == pytest.approx(0, abs=1e-6 * max(1.0, np.abs(fit.spline.derivative()(t)).max()))


def test_fit_axes_uses_axis_tolerances():
    t = np.arange(0, 1.0, 1e-3)
    q = np.stack([np.sin(3 * t) * 10, t**3, t, np.sin(t), np.cos(2 * t)], axis=1)
    fits = fit_axes(t, q, tol_linear=1e-3, tol_rotary=1e-6)
    assert [f.tolerance for f in fits] == [1e-3] * 3 + [1e-6] * 2
    assert fits["C"] is fits[4]
    assert fits(t).shape == (t.size, 5)


@pytest.mark.parametrize("t, x, pattern", [
    (np.arange(3.0), np.zeros(3), "too few samples for a spline fit: 3, need at least 4"),
    (np.arange(5.0), np.array([0, 1, np.nan, 2, 3]), "samples must be finite"),
    (np.array([0, 1, 1, 2, 3.0]), np.zeros(5), "strictly increasing"),
])
def test_bad_input(t, x, pattern):
    with pytest.raises(InputError, match=pattern):
        fit_min_jerk(t, x, 1e-3, name="X")


def test_tolerance_below_round_off_is_an_input_error_not_a_hang():
    t = np.arange(200) * 1e-3
    x = 50.0 + np.sin(7 * t) * 3.0
    with pytest.raises(InputError, match=r"field 'X': the spline fit cannot get within the "
                                         r"tolerance 1e-30: .* use a larger tolerance"):
        fit_min_jerk(t, x, 1e-30, name="X")


def test_warm_start_keeps_the_given_knots_and_needs_fewer_rounds():
    # a corrected command (the original plus a small high-frequency correction) fitted from
    # the original's knots: within tolerance, a superset of them, in fewer rounds
    t = np.arange(0, 20.0, 1e-3)
    s = t / t[-1]
    ramp = 35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7
    envelope = (s * (1 - s)) ** 4 * 256
    x = 50 * ramp + 2 * np.sin(2 * np.pi * (1 + 4 * s) * t) * envelope
    correction = 0.002 * np.sin(2 * np.pi * (3 + 12 * s) * t) * envelope
    original = fit_min_jerk(t, x, 1e-4)
    cold = fit_min_jerk(t, x + correction, 1e-4)
    warm = fit_min_jerk(t, x + correction, 1e-4, initial_knots=original.knot_index)
    assert np.abs(warm(t) - (x + correction)).max() <= 1e-4
    assert np.all(np.isin(original.knot_index, warm.knot_index))
    assert warm.rounds < cold.rounds


def test_rounds_that_add_few_knots_match_the_whole_solve(monkeypatch):
    # rounds adding few knots solve again only around them (LOCAL_REACH knots either side):
    # the result must be the minimum-jerk spline through the final knots, as one whole solve
    # gives it, and C3
    import precontour.prediction.splinefit as splinefit

    chains = []
    solve_chains = splinefit._solve_chains

    def counting(t_knots, x_knots, first, ends, time_scale):
        chains.append(first.size - 1)
        return solve_chains(t_knots, x_knots, first, ends, time_scale)

    monkeypatch.setattr(splinefit, "_solve_chains", counting)
    t = np.arange(0, 30.0, 1e-3)
    s = t / t[-1]
    x = 40 * (35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7)
    for centre in (3.0, 11.0, 17.5, 26.0):      # a few sharp local features
        x = x + 0.05 * np.exp(-((t - centre) / 0.02) ** 2)
    fit = fit_min_jerk(t, x, 1e-5)
    assert max(chains) > 1                      # some round was solved locally
    knots = fit.knot_index
    whole = splinefit._to_ppoly(splinefit._solve_min_jerk(t[knots], x[knots]), t[knots])
    assert np.abs(fit(t) - whole(t)).max() <= 1e-6 * 1e-5
    assert np.abs(fit(t) - x).max() <= 1e-5
    # jerk jumps: the whole solve's own round-off here is 1e-9 of the largest jerk (5 ms
    # segments at the features)
    _check_c3_and_rest(fit.spline, rtol=1e-8)
