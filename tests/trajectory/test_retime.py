"""Local re-timing: the chain rule against finite differences, exact copies outside the
slowed windows, and the slow-down it promises."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.trajectory.retime import added_stretch, held_through_stops, retime
from precontour.trajectory.sampled import Trajectory

TS = 1e-3
W = np.array([3.0, 1.1, 2.3, 0.7, 1.9])          # rad/s of each analytic axis
AMP = np.array([50.0, 20.0, 5.0, 0.3, 0.8])


def _q(s, order=0):
    """Analytic axes AMP sin(W s) and their s-derivatives."""
    phase = W * s[:, None] + order * np.pi / 2
    return AMP * W**order * np.sin(phase)


def _trajectory(n=4000):
    t = np.arange(n) * TS
    P = np.column_stack([t, np.sin(t), np.cos(t)])
    O = np.column_stack([np.sin(0.2 * t), np.zeros(n), np.cos(0.2 * t)])
    return Trajectory(t=t, q=_q(t), P=P, O=O)


def test_chain_rule_against_finite_differences():
    traj = _trajectory()
    stretch = np.ones(traj.n_samples)
    stretch[1800:2100] = 1.8
    result = retime(traj, stretch)
    s = result.old_index * TS                     # old time of each new sample
    new = result.trajectory.q
    # Independent: finite differences of the new samples vs the chain rule with the analytic
    # derivatives of q and finite differences of the time map s(tau).
    r = np.gradient(s, TS)
    r1 = np.gradient(r, TS)
    r2 = np.gradient(r1, TS)
    k = slice(10, s.size - 10)
    qs, qss, qsss = (_q(s, order) for order in (1, 2, 3))
    v = np.gradient(new, TS, axis=0)
    a = np.gradient(v, TS, axis=0)
    j = np.gradient(a, TS, axis=0)
    expect_v = qs * r[:, None]
    expect_a = qss * r[:, None] ** 2 + qs * r1[:, None]
    expect_j = qsss * r[:, None] ** 3 + 3 * qss * (r * r1)[:, None] + qs * r2[:, None]
    scale = lambda x: np.abs(x[k]).max(axis=0)  # noqa: E731
    assert np.all(np.abs(v - expect_v)[k].max(axis=0) <= 1e-4 * scale(expect_v))
    assert np.all(np.abs(a - expect_a)[k].max(axis=0) <= 1e-3 * scale(expect_a))
    assert np.all(np.abs(j - expect_j)[k].max(axis=0) <= 2e-2 * scale(expect_j))
    # The new samples are the old curve at the mapped times (spline accuracy).
    np.testing.assert_allclose(new, _q(s), atol=1e-7 * AMP.max())


def test_slows_by_the_asked_factor_and_copies_elsewhere():
    traj = _trajectory()
    stretch = np.ones(traj.n_samples)
    stretch[2000:2050] = 2.5
    result = retime(traj, stretch)
    rate = np.diff(result.old_index)
    # Speed at the asked samples is at most 1/2.5 of the original.
    asked = (result.old_index[1:] > 2000) & (result.old_index[:-1] < 2049)
    assert rate[asked].max() <= 1 / 2.5 + 1e-9
    # Whole samples added; before and after the window the old samples come back exactly.
    (slow,) = result.slowdowns
    added = result.trajectory.n_samples - traj.n_samples
    assert added > 0 and slow.added == pytest.approx(added * TS)
    # (rounding the window up to whole samples slows it a little more)
    assert 0.4 * (1 - 2e-3) <= slow.speed <= 0.4 + 1e-9
    first = int(slow.start / TS)
    last = int(np.ceil(slow.end / TS))
    np.testing.assert_array_equal(result.trajectory.q[:first], traj.q[:first])
    np.testing.assert_array_equal(result.trajectory.q[last + added:], traj.q[last:])
    np.testing.assert_array_equal(result.trajectory.P[last + added:], traj.P[last:])
    assert slow.start < 2000 * TS and slow.end > 2050 * TS
    np.testing.assert_allclose(np.linalg.norm(result.trajectory.O, axis=1), 1.0)


def test_nothing_to_slow_is_the_identity():
    traj = _trajectory(500)
    result = retime(traj, np.full(500, 0.7))
    assert result.slowdowns == ()
    np.testing.assert_array_equal(result.trajectory.q, traj.q)
    np.testing.assert_array_equal(result.old_index, np.arange(500))


def test_lines_follow_the_samples():
    traj = _trajectory()
    line = np.repeat(np.arange(100, 140), 100)
    stretch = np.ones(traj.n_samples)
    stretch[1000:1010] = 3.0
    result = retime(traj, stretch, line=line)
    assert np.all(np.diff(result.line) >= 0)
    assert set(result.line) == set(line)
    (slow,) = result.slowdowns
    assert slow.lines[0] <= 110 <= slow.lines[1]


def test_added_stretch_covers_the_need_smoothly():
    need = np.ones(3000)
    need[1500] = 1.4
    need[2200:2210] = 1.1
    added = added_stretch(need, TS)
    assert added[1499] >= 0.4 and added[1500] >= 0.4 and added[2205] >= 0.1
    # Each window adds whole samples, and the stretch is smooth (small second differences).
    on = np.concatenate([[0], (added > 0).astype(int), [0]])
    edges = np.flatnonzero(np.diff(on))
    for a, b in zip(edges[::2], edges[1::2]):
        assert added[a:b].sum() == pytest.approx(round(added[a:b].sum()), abs=1e-9)
    assert np.abs(np.diff(added, 2)).max() < 1e-3


def _move_rest_move(ts=0.001):
    """X: a move (speed rising smoothly over 0.1 s, held 0.2 s, falling over 0.1 s), a rest of
    0.2 s, the same move again, a rest; the other axes rest throughout. Returns q (N, 5)."""
    ramp = lambda s: 3 * s**2 - 2 * s**3                        # noqa: E731
    up = ramp(np.linspace(0.0, 1.0, 101))[1:]
    speed = np.concatenate([up, np.ones(200), up[::-1], np.zeros(200)])
    x = np.concatenate([[0.0], np.cumsum(np.tile(speed, 2)) * ts])
    q = np.zeros((x.size, 5))
    q[:, 0] = x
    return q


def test_held_through_stops_spreads_a_need_in_a_rest_over_its_approach_and_start():
    """A need within a rest (the corrections settling after a stop) is held over the whole
    deceleration into it and the whole acceleration out of it, known here from how
    :func:`_move_rest_move` is built (sample k's step is speed k - 1: the first deceleration
    is samples 301-400, the rest 401-600, the next acceleration 601-700); the first
    acceleration and the cruises are left as they are."""
    q = _move_rest_move()
    assert np.all(np.diff(q[400:601, 0]) == 0.0) and np.diff(q[:, 0])[399] > 0.0
    stretch = np.ones(q.shape[0])
    stretch[450] = 1.3
    held = held_through_stops(stretch, q)
    assert np.all(held[301:401] == 1.3)
    assert np.all(held[601:700] == 1.3)
    assert held[450] == 1.3
    assert np.all(held[:299] == 1.0)
    assert np.all(held[403:450] == 1.0) and np.all(held[451:599] == 1.0)
    assert np.all(held[702:] == 1.0)


def test_held_through_stops_leaves_needs_away_from_rests():
    """A need in a cruise (the speed neither falling to a rest nor rising from one) is left as
    it is, and so is a stretch that asks for nothing."""
    q = _move_rest_move()
    stretch = np.ones(q.shape[0])
    np.testing.assert_array_equal(held_through_stops(stretch, q), stretch)
    stretch[200] = 1.2                       # the first cruise (samples 101-300)
    np.testing.assert_array_equal(held_through_stops(stretch, q), stretch)
