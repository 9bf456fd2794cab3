"""The nearest-sample search of the closest-point search (prediction/contour.py) against a
brute-force scan of the window, on references that rest, creep, come back near themselves or
repeat samples bit for bit, and its cost where the reference nearly rests (issue 39: the
walk over nearly coincident samples made the search's cost grow with the window there)."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from precontour.prediction import contour
from precontour.prediction.contour import ReferencePath


def _brute(samples, point, lo, hi):
    """Smallest distance of samples[lo..hi] from point, computed as the search computes it
    (the same operations in the same order: equal bit for bit)."""
    window = samples[lo:hi + 1]
    return np.sqrt(((window[:, 0] - point[0]) ** 2 + (window[:, 1] - point[1]) ** 2)
                   + (window[:, 2] - point[2]) ** 2).min()


def _stretches(rng, n):
    """Tip samples made of stretches of random kinds: moving (20 um per sample), slowed
    (1 nm), creeping (1e-12 mm: round-off of the coordinates), exactly at rest (the same
    sample repeated), a hairpin back along the way it came, and a jump."""
    steps = np.empty((n, 3))
    k = 0
    while k < n:
        length = int(rng.integers(5, 600))
        kind = rng.integers(6)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        size = [2e-2, 1e-6, 1e-12, 0.0, 2e-2, 0.0][kind]
        block = np.tile(direction * size, (length, 1))
        if kind == 4:                                   # there and back
            block[length // 2:] *= -1.0
        block += rng.normal(size=block.shape) * size * 0.2 * (kind != 4)
        if kind == 5:
            block[0] = rng.normal(size=3)                # a jump of about 1 mm
        steps[k:k + length] = block[:n - k]
        k += length
    return np.array([120.0, -40.0, 300.0]) + np.cumsum(steps, axis=0)


def _points(rng, samples, count):
    """Points near samples (from 1e-12 mm to 1 mm off), some of them lagging a few to a
    thousand samples behind the sample of their index, as the actual does near a stop."""
    n = samples.shape[0]
    index = rng.integers(0, n, count)
    source = np.clip(index - rng.integers(0, 1000, count) * (rng.random(count) < 0.5), 0,
                     n - 1)
    scale = 10.0 ** rng.uniform(-12, 0, count)
    return index, samples[source] + rng.normal(size=(count, 3)) * scale[:, None]


def _reference(samples, orientation=False):
    t = np.arange(samples.shape[0]) * 1e-3
    O = np.tile([0.0, 0.0, 1.0], (t.size, 1))
    if orientation:
        return ReferencePath.from_samples(t, np.zeros_like(samples), samples)
    return ReferencePath.from_samples(t, samples, O)


def _check_nearest(ref, arrays, isolation, points, index, lo, hi):
    _, _, samples, tree = arrays
    for i, point, a, b in zip(index, points, lo, hi):
        k = contour._nearest_sample(samples, tree, isolation, point, i, a, b)
        assert a <= k <= b
        # the distance of the sample found is the brute-force minimum, bit for bit (a
        # different sample only at an exactly equal distance)
        assert _brute(samples, point, k, k) == _brute(samples, point, a, b)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1))
def test_nearest_sample_is_the_brute_force_one(seed):
    rng = np.random.default_rng(seed)
    samples = _stretches(rng, int(rng.integers(50, 4000)))
    ref = _reference(samples)
    base, lo, hi = ref._own_windows
    index, points = _points(rng, samples, 80)
    # the search's own windows (where the isolation may decide) ...
    _check_nearest(ref, ref._tip_arrays, ref._tip_isolation, points, index, lo[index],
                   hi[index])
    # ... and arbitrary ones around the start sample (where the tree does)
    a = np.clip(index - rng.integers(0, 3000, index.size), 0, None)
    b = np.clip(index + rng.integers(0, 3000, index.size), None, samples.shape[0] - 1)
    _check_nearest(ref, ref._tip_arrays, ref._tip_isolation, points, index, a, b)


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1))
def test_nearest_orientation_sample_is_the_brute_force_one(seed):
    # unit vectors (the orientation curve): resting, creeping and turning back
    rng = np.random.default_rng(seed)
    raw = _stretches(rng, int(rng.integers(50, 3000))) - np.array([120.0, -40.0, 300.0])
    samples = (raw + [0.0, 0.0, 10.0]) / np.linalg.norm(raw + [0.0, 0.0, 10.0],
                                                        axis=1)[:, None]
    ref = _reference(samples, orientation=True)
    base, lo, hi = ref._own_windows
    index, points = _points(rng, samples, 80)
    _check_nearest(ref, ref._orientation_arrays, ref._orientation_isolation, points, index,
                   lo[index], hi[index])


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1))
def test_isolation_is_the_brute_force_distance(seed):
    rng = np.random.default_rng(seed)
    samples = _stretches(rng, int(rng.integers(50, 3000)))
    ref = _reference(samples)
    isolated, lower, upper = ref._tip_isolation
    n = samples.shape[0]
    for block in rng.choice(isolated.size, min(isolated.size, 40), replace=False):
        first, last, centre = contour._block_core(block, n)
        others = np.r_[lower[block]:max(first, lower[block]),
                       min(last + 1, upper[block] + 1):upper[block] + 1]
        point = samples[centre]
        expected = min((_brute(samples, point, j, j) for j in others), default=np.inf)
        assert isolated[block] == expected


def _resting_reference(n, step=1e-6):
    """A reference that slows to ``step`` mm per sample over all but its first and last 2,000
    samples, along a gentle curve; the actual lags 2-8 um behind it and creeps 2 um aside."""
    speed = np.full(n, step)
    speed[:2000] = np.linspace(0.05, step, 2000)
    speed[-2000:] = np.linspace(step, 0.05, 2000)
    arc = np.concatenate([[0.0], np.cumsum(speed[1:])])
    direction = np.array([1.0, 0.6, -0.2]) / np.linalg.norm([1.0, 0.6, -0.2])
    origin = np.array([10.0, -5.0, 200.0])
    bend = np.array([0.0, 0.0, 1e-4])
    P = origin + arc[:, None] * direction + np.sin(arc / 0.01)[:, None] * bend
    t = np.arange(n) * 1e-3
    lag = 5e-3 + 3e-3 * np.sin(t / 7.0)
    creep = 2e-3 * np.stack([np.sin(t / 3.0), np.cos(t / 5.0), np.sin(t / 11.0)], axis=1)
    actual = origin + (arc - lag)[:, None] * direction + creep
    return ReferencePath.from_samples(t, P, np.tile([0.0, 0.0, 1.0], (n, 1))), actual


def test_search_on_a_resting_stretch_visits_few_samples(monkeypatch):
    """Where the reference nearly rests (1 nm per sample, 2,000-sample windows) and the actual
    lags microns behind it along its line, the distance falls monotonically across the whole
    window: the scan's triangle-inequality skips advanced one sample at a time there, the tree
    rules out all but the nodes on the way to the nearest sample. Counted on the interpreted
    search (the compiled one is the same code)."""
    ref, actual = _resting_reference(30_000)
    base, lo, hi = ref._own_windows
    _, _, samples, (radii, offsets) = ref._tip_arrays
    calls = {"distance": 0}
    for name in ("_chord", "_to_segment"):
        compiled = getattr(contour, name)

        def counted(*args, compiled=compiled):
            calls["distance"] += 1
            return compiled(*args)
        monkeypatch.setattr(contour, name, counted)
    for i in (8_000, 15_000, 22_000):
        assert hi[i] - lo[i] >= 1_900
        calls["distance"] = 0
        stack, bounds = np.empty(contour._STACK, dtype=np.int64), np.empty(contour._STACK)
        k, d = contour._tree_nearest.py_func(radii, offsets, samples, actual[i], lo[i], hi[i],
                                             base[i], -1, np.inf, stack, bounds)
        assert d == _brute(samples, actual[i], lo[i], hi[i])
        assert calls["distance"] < 60


@pytest.mark.parametrize("edge", ["lo", "hi"])
def test_exact_rest_at_the_window_edge(edge):
    """A window whose edge lies in a stretch exactly at rest (the same sample repeated) and a
    point beyond it: the search ends (the scan it replaced once looped forever there, on a
    371,156-sample piece of LinuxCNC's boat example) with the brute-force distance, compiled
    and interpreted."""
    n = 4_000
    P = np.zeros((n, 3))
    P[:, 0] = np.concatenate([np.linspace(0.0, 20.0, 1_500), np.full(1_000, 20.0),
                              np.linspace(20.0, 40.0, 1_500)])
    P[:, 0] += 22.73889240841357           # a chord length whose last digit is not zero
    samples = np.ascontiguousarray(P)
    radii, offsets = contour._capsule_tree(samples)
    # the point beyond the window's resting edge, 1 um off the line
    a, b = (2_000, 3_000) if edge == "lo" else (1_000, 2_000)
    point = samples[a if edge == "lo" else b] + [-1e-3 if edge == "lo" else 1e-3, 1e-3, 0.0]
    base = (a + b) // 2
    distances = np.array([_brute(samples, point, j, j) for j in range(a, b + 1)])
    ties = a + np.flatnonzero(distances == distances.min())
    assert ties.size > 400
    # of equal distances: the start, else the nearest above it, else the nearest below it
    above, below = ties[ties > base], ties[ties < base]
    expected = (base if base in ties else above.min() if above.size else below.max())
    for search in (contour._tree_nearest.py_func, contour._tree_nearest):
        stack, bounds = np.empty(contour._STACK, dtype=np.int64), np.empty(contour._STACK)
        k, d = search(radii, offsets, samples, point, a, b, base, -1, np.inf, stack, bounds)
        assert d == distances.min()
        assert k == expected


def test_contour_errors_on_a_resting_stretch_are_the_brute_force_ones():
    """The contour errors where the reference nearly rests: at least as small as the
    brute-force nearest sample's distance, and Newton's refinement of it (the same sample is
    found, so the same errors)."""
    ref, actual = _resting_reference(12_000)
    err = ref.errors(actual, np.tile([0.0, 0.0, 1.0], (actual.shape[0], 1)))
    base, lo, hi = ref._own_windows
    samples = ref._tip_arrays[2]
    for i in range(0, actual.shape[0], 97):
        assert err.tip[i] <= _brute(samples, actual[i], lo[i], hi[i]) + 1e-15
