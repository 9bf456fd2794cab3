from dataclasses import replace

import numpy as np
import pytest

from precontour import load_machine
from precontour.trajectory.builtin_paths import builtin_path
from precontour.errors import PrecontourError
from precontour.trajectory.feedplan import _acceleration_passes, axis_limits, plan_feed
from precontour.trajectory.pathspline import fit_path, fit_toolpath

TS = 0.001
RTOL = 1e-9


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def _check_limits(profile, machine, feed=100.0, acceleration=2000.0, jerk=50000.0,
                  feed_of_s=None):
    """Independent check of every limit on every sample with finite differences."""
    ts = profile.ts
    v, a, j = axis_limits(machine)
    q, P, s = profile.q, profile.P, profile.s
    assert np.all(np.abs(np.diff(q, axis=0)) / ts <= v * (1 + RTOL))
    assert np.all(np.abs(np.diff(q, 2, axis=0)) / ts**2 <= a * (1 + RTOL))
    assert np.all(np.abs(np.diff(q, 3, axis=0)) / ts**3 <= j * (1 + RTOL))
    tip_speed = np.linalg.norm(np.diff(P, axis=0), axis=1) / ts
    limit = feed if feed_of_s is None else feed_of_s(0.5 * (s[1:] + s[:-1]))
    assert np.all(tip_speed <= limit * (1 + RTOL) + 1e-9)
    assert np.all(np.linalg.norm(np.diff(P, 2, axis=0), axis=1) / ts**2
                  <= acceleration * (1 + RTOL))
    assert np.all(np.abs(np.diff(s, 3)) / ts**3 <= jerk * (1 + RTOL))
    assert np.all(np.diff(s) >= 0)
    # At rest at both ends, to within one sample of the jerk limit.
    for end in (np.diff(s[:3]), np.diff(s[-3:])):
        assert np.all(end / ts <= jerk * ts**2)


def test_acceleration_passes_match_brute_force():
    rng = np.random.default_rng(1)
    n, h = 300, 0.1
    v_lim = rng.uniform(5, 100, n)
    a_lim = rng.uniform(500, 3000, n)
    v = _acceleration_passes(v_lim.copy(), a_lim, h)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (a_lim[1:] + a_lim[:-1]) * h)])
    v2 = v_lim**2
    v2[0] = v2[-1] = 0
    brute = np.array([min(v2[k] + 2 * abs(sigma[i] - sigma[k]) for k in range(n))
                      for i in range(n)])
    np.testing.assert_allclose(v**2, np.minimum(brute, v2), rtol=1e-12, atol=1e-9)
    # Consecutive squared speeds change by at most 2 * integral of a_lim (the passes' bound).
    assert np.all(np.abs(np.diff(v**2)) <= 2 * np.diff(sigma) * (1 + 1e-12))


@pytest.mark.parametrize("name", ["paper", "cone"])
def test_all_limits_hold_on_every_sample(machine, name):
    profile = plan_feed(fit_toolpath(builtin_path(name)), machine)
    _check_limits(profile, machine)
    assert profile.s[0] == 0 and abs(profile.s[-1] - fit_toolpath(builtin_path(name)).length) < 1e-9
    np.testing.assert_allclose(profile.t, np.arange(profile.t.size) * TS)


def test_tight_axis_limits_are_respected_and_slow_the_path(machine):
    path = fit_toolpath(builtin_path("paper"))
    fast = plan_feed(path, machine)
    drives = list(machine.drives)
    drives[4] = replace(drives[4], v_max=0.8, a_max=10.0, j_max=200.0)
    drives[3] = replace(drives[3], v_max=0.8)
    slow_machine = replace(machine, drives=tuple(drives))
    slow = plan_feed(path, slow_machine)
    _check_limits(slow, slow_machine)
    assert slow.t[-1] > fast.t[-1] * 1.2
    assert np.abs(np.diff(slow.q[:, 4])).max() / TS > 0.7  # the C limit is actually reached


def test_programmed_feed_is_respected(machine):
    u = np.linspace(0, 1, 101)
    P = np.stack([200 * u, 20 * np.sin(3 * u), np.zeros_like(u)], axis=-1)
    O = np.tile([0.0, np.sin(0.3), np.cos(0.3)], (u.size, 1))
    feed = np.where(u <= 0.5, 40.0, np.nan)  # NaN: the maximum feed applies
    path = fit_path(P, O)
    profile = plan_feed(path, machine, programmed_feed=feed)
    s_half = path.s_points[50]
    _check_limits(profile, machine, feed_of_s=lambda s: np.where(s <= s_half, 40.0, 100.0))
    tip_speed = np.linalg.norm(np.diff(profile.P, axis=0), axis=1) / TS
    mid = 0.5 * (profile.s[1:] + profile.s[:-1])
    assert tip_speed[mid < s_half].max() > 38.0
    assert tip_speed[mid > s_half].max() > 90.0


def test_lower_feed_and_jerk_options(machine):
    path = fit_toolpath(builtin_path("circle"))
    profile = plan_feed(path, machine, feed=50.0, acceleration=800.0, jerk=10000.0)
    _check_limits(profile, machine, feed=50.0, acceleration=800.0, jerk=10000.0)
    assert profile.t[-1] > path.length / 50.0


@pytest.mark.parametrize("kwargs, match", [
    ({"feed": 0.0}, "feed must be positive and finite, got 0.0"),
    ({"ts": -1.0}, "ts must be positive and finite"),
    ({"jerk": np.inf}, "jerk must be positive and finite"),
    ({"programmed_feed": np.r_[np.nan, -5.0, np.ones(498)]},
     "row 2, field 'feed': programmed feed must be positive, got -5 mm/s"),
    ({"programmed_feed": np.ones(7)},
     r"field 'feed': programmed feed must have one entry per point, got shape \(7,\)"),
    ({"grid_step": 0.0}, "grid_step must be positive and finite, got 0.0"),
])
def test_bad_arguments(machine, kwargs, match):
    with pytest.raises(ValueError, match=match):
        plan_feed(fit_toolpath(builtin_path("paper")), machine, **kwargs)


def test_singular_orientation_is_refused(machine):
    # The orientation passes through straight down (A = pi), where A-C trunnion A jumps.
    phi = np.linspace(2.6, 3.6, 41)
    P = np.stack([np.linspace(0, 40, 41), np.zeros(41), np.zeros(41)], axis=-1)
    O = np.stack([np.sin(phi), np.zeros(41), np.cos(phi)], axis=-1)
    with pytest.raises(PrecontourError, match="axis A jumps by .* rad within .* mm near s = .*singular direction"):
        plan_feed(fit_path(P, O), machine)


def test_runaway_duration_is_refused(machine):
    with pytest.raises(PrecontourError, match="more than 1000 samples"):
        plan_feed(fit_toolpath(builtin_path("paper")), machine, max_samples=1000)


def test_c_jump_too_close_to_vertical_is_refused(machine):
    # Passing 1e-6 rad from vertical: C would turn half a revolution within one grid step.
    u = np.linspace(0, 1, 41)
    phi = 0.5 - u
    P = np.stack([60 * u, np.zeros_like(u), np.zeros_like(u)], axis=-1)
    O = np.stack([np.sin(phi), np.full_like(u, 1e-6), np.cos(phi)], axis=-1)
    O /= np.linalg.norm(O, axis=1)[:, None]
    with pytest.raises(PrecontourError, match="axis C jumps by .* too close to A = 0"):
        plan_feed(fit_path(P, O), machine)
