import numpy as np
import pytest

from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.errors import InputError
from precontour.trajectory.sampled import Trajectory

from conftest import smoothstep7

T = np.arange(0, 2.0 + 5e-4, 1e-3)


def _arc_reference(radius=40.0):
    phi = 2.5 * smoothstep7(T / T[-1])                       # rest to rest along an arc
    P = np.stack([radius * np.cos(phi), radius * np.sin(phi), 5.0 * phi], axis=1)
    tilt = 0.3 + 0.4 * smoothstep7(T / T[-1])
    O = np.stack([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)], axis=1)  # swings in x-z
    return phi, tilt, P, O


def test_sideways_offset_gives_its_distance():
    phi, tilt, P, O = _arc_reference()
    ref = ReferencePath.from_samples(T, P, O)
    d = 0.025  # mm, along the horizontal normal of the helix (perpendicular to its tangent)
    normal = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=1)
    # lag the actual along the path too (time shift of 3 ms): the contour error ignores it
    lag = np.interp(T - 0.003, T, np.arange(T.size)).astype(float)
    P_lag = np.stack([np.interp(lag, np.arange(T.size), P[:, i]) for i in range(3)], axis=1)
    phi_lag = np.interp(lag, np.arange(T.size), phi)
    normal_lag = np.stack([np.cos(phi_lag), np.sin(phi_lag), 0 * phi_lag], axis=1)
    # orientation tilted sideways (perpendicular to its path) by a known angle
    delta = 2e-4
    O_side = np.cos(delta) * O + np.sin(delta) * np.array([0.0, 1.0, 0.0])
    err = ref.errors(P_lag + d * normal_lag, O_side)
    np.testing.assert_allclose(err.tip, d, rtol=2e-4)
    np.testing.assert_allclose(err.orientation, delta, rtol=1e-3)
    del normal


def test_newton_agrees_with_brute_force_dense_search():
    rng = np.random.default_rng(3)
    phi, tilt, P, O = _arc_reference()
    ref = ReferencePath.from_samples(T, P, O)
    P_act = P + rng.normal(0, 0.02, P.shape)
    O_act = O + rng.normal(0, 2e-4, O.shape)
    O_act /= np.linalg.norm(O_act, axis=1, keepdims=True)
    err = ref.errors(P_act, O_act)
    # brute force: the spline on a dense grid over the same search window (50 ms either side,
    # widened to 2 mm of path progress where the path is slow)
    picks = np.arange(0, T.size, 37)
    _, lo, hi = ref._window(T[picks], 0.05, 2.0)
    for k, a, b in zip(picks, T[lo], T[hi]):
        u = np.linspace(a, b, 20 * int(round((b - a) / 1e-3)) + 1)
        curve = ref.tip(u)
        distances = np.linalg.norm(curve - P_act[k], axis=1)
        tip = distances.min()
        # a grid of spacing h misses the optimum at distance d by at most about h^2 / (8 d)
        h = np.linalg.norm(np.diff(curve, axis=0), axis=1).max()
        Ou = ref.orientation(u)
        Ou /= np.linalg.norm(Ou, axis=1, keepdims=True)
        angles = np.arctan2(np.linalg.norm(np.cross(Ou, O_act[k]), axis=1), Ou @ O_act[k])
        ori = angles.min()
        h_ori = np.linalg.norm(np.diff(Ou, axis=0), axis=1).max()
        assert err.tip[k] <= tip + 1e-12
        assert err.tip[k] >= tip - 1.5 * h**2 / (8 * tip)
        assert err.orientation[k] <= ori + 1e-9
        assert err.orientation[k] >= ori - 1.5 * h_ori**2 / (8 * ori)


def test_window_keeps_the_time_corresponding_branch():
    # a hairpin: the path comes back 10 um beside itself; the actual on the way back must be
    # measured against the way back, not the way out
    s = smoothstep7(T / T[-1])
    x = 30 * np.sin(np.pi * s)                       # out and back along x
    y = np.where(s > 0.5, 0.010, 0.0) * smoothstep7((s - 0.45) / 0.1)
    P = np.stack([x, y, np.zeros_like(x)], axis=1)
    O = np.tile([0.0, 0.0, 1.0], (T.size, 1))
    ref = ReferencePath.from_samples(T, P, O)
    back = T > 1.5
    P_act = P.copy()
    P_act[back, 1] += 0.002                          # 2 um off the way back, 12 um off the way out
    err = ref.errors(P_act, O)
    np.testing.assert_allclose(err.tip[back], 0.002, rtol=1e-6)


def test_contour_errors_from_axes(machine):
    _, _, P, O = _arc_reference()
    q = machine.kinematics.inverse(P, O)
    ref = ReferencePath.from_trajectory(Trajectory(T, q, P, O))
    err = contour_errors(ref, q, machine.kinematics)
    assert err.tip.max() < 1e-9 and err.orientation.max() < 1e-9
    assert set(err.summary()) == {"tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad"}


def test_reference_needed():
    with pytest.raises(InputError, match="Px,Py,Pz,Oi,Oj,Ok"):
        ReferencePath.from_trajectory(Trajectory(T, np.zeros((T.size, 5))))


def test_nearest_sample_and_isolation_match_brute_force():
    # a path that doubles back on itself within the search window (hairpins 0.1 mm apart):
    # where the samples around the nearest one are not isolated the tree search must decide
    from precontour.prediction import contour

    rng = np.random.default_rng(7)
    t = np.arange(0, 1.0, 1e-3)
    x = 0.5 * np.sin(2 * np.pi * 12 * t)                 # back and forth, 24 turns
    P = np.stack([x, 0.1 * np.floor(24 * t), np.zeros_like(t)], axis=1)
    ref = ReferencePath.from_samples(t, P, np.tile([0.0, 0.0, 1.0], (t.size, 1)))
    _, _, samples, tree = ref._tip_arrays
    base, lo, hi = ref._own_windows
    isolated, lower, upper = ref._tip_isolation
    for block in rng.choice(isolated.size, 60, replace=False):
        first, last, centre = contour._block_core(block, t.size)
        others = np.r_[lower[block]:max(first, lower[block]),
                       min(last + 1, upper[block] + 1):upper[block] + 1]
        expected = np.linalg.norm(samples[others] - samples[centre], axis=1).min(initial=np.inf)
        assert isolated[block] == pytest.approx(expected, rel=1e-12)
    points = P + rng.normal(0, 0.05, P.shape)
    for i in rng.choice(t.size, 300, replace=False):
        k = contour._nearest_sample(samples, tree, ref._tip_isolation, points[i], base[i],
                                    lo[i], hi[i])
        distances = np.linalg.norm(samples[lo[i]:hi[i] + 1] - points[i], axis=1)
        assert lo[i] <= k <= hi[i]
        assert np.linalg.norm(samples[k] - points[i]) <= distances.min() * (1 + 1e-12)


def test_nearest_sample_on_a_creeping_stretch_matches_brute_force():
    """A reference that creeps (steps of 3e-10 mm, within the round-off of its chord length)
    and rests exactly, as a heavily slowed program does at its stops: the nearest sample of points
    near it and the contour errors are those of a brute-force search over the window."""
    from precontour.prediction import contour

    rng = np.random.default_rng(11)
    n = 20_000
    t = np.arange(n) * 1e-3
    # the speed eases (C2, over 0.3 s) from 20 mm/s down to a creep of 3e-7 mm/s (3e-10 mm
    # per sample) for 8 s, back up, and down to rest for 1 s, as a retimed program does
    k = np.arange(n - 1)
    ease = lambda x: np.clip(x, 0, 1) ** 3 * (10 - 15 * np.clip(x, 0, 1)
                                             + 6 * np.clip(x, 0, 1) ** 2)
    creep = ease((k - 5_700) / 300) * (1 - ease((k - 14_000) / 300))
    rest = ease((k - 14_700) / 300) * (1 - ease((k - 16_000) / 300))
    step = 0.02 * (1 - creep) + 3e-10 * creep
    step = step * (1 - rest)
    s = np.concatenate([[0.0], np.cumsum(step)])
    P = np.stack([s, 0.2 * np.sin(s / 10), np.zeros(n)], axis=1)
    O = np.tile([0.0, 0.0, 1.0], (n, 1))
    ref = ReferencePath.from_samples(t, P, O)
    _, _, samples, tree = ref._tip_arrays
    base, lo, hi = ref._own_windows
    points = P + rng.normal(0, 1e-3, P.shape)
    picks = np.concatenate([rng.choice(np.arange(5_500, 16_500), 400, replace=False),
                            rng.choice(n, 100, replace=False)])
    for i in picks:
        k = contour._nearest_sample(samples, tree, ref._tip_isolation, points[i], base[i],
                                    lo[i], hi[i])
        distances = np.linalg.norm(samples[lo[i]:hi[i] + 1] - points[i], axis=1)
        assert lo[i] <= k <= hi[i]
        assert np.linalg.norm(samples[k] - points[i]) <= distances.min() * (1 + 1e-12)
    err = ref.errors(points, O)
    for i in picks[:60]:
        u = np.linspace(t[lo[i]], t[hi[i]], 50 * (hi[i] - lo[i]) + 1)
        curve = ref.tip(u)
        distances = np.linalg.norm(curve - points[i], axis=1)
        dense = distances.min()
        # a grid of spacing h misses the optimum at distance d by at most about h^2 / (8 d)
        h = np.linalg.norm(np.diff(curve, axis=0), axis=1).max()
        assert err.tip[i] <= dense + 1e-12
        assert err.tip[i] >= dense - 1.5 * h**2 / (8 * dense) - 1e-12
