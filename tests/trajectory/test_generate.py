import numpy as np
import pytest

from precontour import load_machine
from precontour.trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
from precontour.errors import InputError, ToolPathError
from precontour.trajectory.feedplan import axis_limits
from precontour.toolpath import ToolPath
from precontour.trajectory.generate import generate_trajectory, summarize

TS = 0.001


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


@pytest.fixture(scope="module")
def trajectories(machine):
    return {name: generate_trajectory(builtin_path(name), machine) for name in BUILTIN_PATHS}


def _within_limits(tr, machine, feed=100.0):
    v, a, j = axis_limits(machine)
    q = tr.q
    ok = (np.all(np.abs(np.diff(q, axis=0)) / TS <= v * (1 + 1e-9))
          and np.all(np.abs(np.diff(q, 2, axis=0)) / TS**2 <= a * (1 + 1e-9))
          and np.all(np.abs(np.diff(q, 3, axis=0)) / TS**3 <= j * (1 + 1e-9)))
    tip = np.linalg.norm(np.diff(tr.P, axis=0), axis=1) / TS
    return ok and tip.max() <= feed * (1 + 1e-9)


@pytest.mark.parametrize("name", BUILTIN_PATHS)
def test_builtins_respect_limits_and_fk_reproduces_reference(machine, trajectories, name):
    tr = trajectories[name]
    assert _within_limits(tr, machine)
    assert summarize(tr, machine).within_limits
    P, O = machine.kinematics.forward(tr.q)
    assert np.abs(P - tr.P).max() < 1e-9
    assert np.abs(O - tr.O).max() < 1e-9
    np.testing.assert_allclose(tr.t, np.arange(tr.n_samples) * TS, atol=1e-12)
    assert np.all(np.isfinite(tr.q))
    # Starts and stops at rest: end velocities below 0.1 % of each axis's peak.
    peak = np.abs(np.diff(tr.q, axis=0)).max(axis=0)
    for end in (tr.q[:3], tr.q[-3:]):
        assert np.all(np.abs(np.diff(end, axis=0)) <= 1e-3 * peak + 1e-9)


def test_paper_path_resembles_the_papers(trajectories):
    tr = trajectories["paper"]
    extent = np.ptp(tr.P, axis=0)
    assert 95 < extent[0] < 105 and 55 < extent[1] < 65 and 30 < extent[2] < 45
    A, C = tr.q[:, 3], tr.q[:, 4]
    assert 1.45 < A.max() < 1.55 and A.min() > 0.2
    assert 1.8 < np.ptp(C) < 2.2
    assert 2.3 < tr.duration < 2.9
    radius = np.hypot(tr.P[:, 0], tr.P[:, 1])
    assert radius.min() > 10


def test_path_through_a_equal_zero(machine):
    # Tool swings from a +x tilt through vertical to a -x tilt while the tip moves.
    u = np.linspace(0, 1, 41)
    phi = 0.5 - u
    P = np.stack([60 * u - 30, np.full_like(u, 10.0), 5 * np.sin(np.pi * u)], axis=-1)
    O = np.stack([np.sin(phi), np.zeros_like(u), np.cos(phi)], axis=-1)
    tr = generate_trajectory(ToolPath(P=P, O=O), machine)
    assert np.all(np.isfinite(tr.q))
    assert np.abs(np.diff(tr.q[:, 4])).max() < 1e-12  # C held: the tool stays in one plane
    assert tr.q[:, 3].min() < -0.49 and tr.q[:, 3].max() > 0.49
    assert _within_limits(tr, machine)
    Pf, Of = machine.kinematics.forward(tr.q)
    assert np.abs(Pf - tr.P).max() < 1e-9 and np.abs(Of - tr.O).max() < 1e-9


def test_path_grazing_a_equal_zero_slows_for_c(machine):
    # Passing 2 mrad from vertical: C must turn half a revolution; limits still hold.
    u = np.linspace(0, 1, 41)
    phi = 0.5 - u
    P = np.stack([60 * u - 30, np.full_like(u, 10.0), 5 * np.sin(np.pi * u)], axis=-1)
    O = np.stack([np.sin(phi), np.full_like(u, 2e-3), np.cos(phi)], axis=-1)
    O /= np.linalg.norm(O, axis=1)[:, None]
    tr = generate_trajectory(ToolPath(P=P, O=O), machine)
    assert np.ptp(tr.q[:, 4]) > 3.0
    assert _within_limits(tr, machine)


def test_round_trip_through_sampled_points(machine, trajectories, tmp_path):
    first = trajectories["paper"]
    keep = np.r_[0:first.n_samples:5, first.n_samples - 1]
    # Write every fifth sample's P, O as text and read it back as a new tool path.
    np.savetxt(tmp_path / "cl.txt", np.hstack([first.P[keep], first.O[keep]]), fmt="%.12g")
    data = np.loadtxt(tmp_path / "cl.txt")
    again = generate_trajectory(ToolPath(P=data[:, :3], O=data[:, 3:]), machine)
    assert abs(again.duration - first.duration) < 0.02 * first.duration
    # Same geometry: every new sample lies on the first path (nearest dense sample).
    from scipy.spatial import cKDTree
    dist, _ = cKDTree(first.P).query(again.P)
    step = np.linalg.norm(np.diff(first.P, axis=0), axis=1).max()
    assert dist.max() < 0.5 * step + 1e-4


def test_summary_numbers_and_text(machine, trajectories):
    tr = trajectories["circle"]
    summary = summarize(tr, machine)
    assert summary.n_samples == tr.n_samples
    assert summary.duration == pytest.approx(tr.duration)
    np.testing.assert_allclose(summary.peak_velocity,
                               np.abs(np.gradient(tr.q, TS, axis=0)).max(axis=0), rtol=0.02)
    assert 99.0 < summary.peak_feed <= 100.0 * (1 + 1e-9)
    text = str(summary)
    assert "peak feed 100.00 mm/s" in text and len(text.splitlines()) == 7
    assert text.splitlines()[-1].startswith("C")


def test_errors_reach_the_caller(machine):
    with pytest.raises(ToolPathError, match="a.nc: a tool path needs at least 2 points, got 1"):
        generate_trajectory(ToolPath(P=np.zeros((1, 3)), O=np.array([[0, 0, 1.0]]),
                                     source="a.nc"), machine)
    with pytest.raises(InputError, match="unknown built-in path 'spiral'; choose one of paper"):
        builtin_path("spiral")
    with pytest.raises(InputError, match="built-in path 'circle': .*unexpected keyword"):
        builtin_path("circle", radus=3)
    with pytest.raises(InputError, match="field 'radius': radius must be > 0 mm, got -1"):
        builtin_path("circle", radius=-1)


def _distance_to_polyline(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` to the polyline through ``corners``."""
    best = np.full(points.shape[0], np.inf)
    for a, b in zip(corners[:-1], corners[1:]):
        ab = b - a
        u = np.clip((points - a) @ ab / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(a + u[:, None] * ab - points, axis=1))
    return best


def test_a_polyline_of_cl_points_is_followed_with_a_stop_at_each_corner(machine):
    """Four points of a 40 x 4 mm rectangle's three sides, the tool vertical (APT GOTOs are
    straight moves): the tool tip stays on the polyline (one spline through the four points
    left it by 23.5 mm), stops at both corners, and the trajectory keeps every limit; the
    axes continue where they stopped (forward kinematics reproduce the reference)."""
    corners = np.array([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [40.0, 4.0, 0.0], [0.0, 4.0, 0.0]])
    toolpath = ToolPath(P=corners, O=np.tile([0.2, 0.0, 1.0], (4, 1)) / np.hypot(0.2, 1.0),
                        source="rectangle")
    tr = generate_trajectory(toolpath, machine, lines=np.array([11, 12, 13, 14]))
    assert _distance_to_polyline(tr.P, corners).max() < 1e-9
    assert _within_limits(tr, machine) and summarize(tr, machine).within_limits
    P, O = machine.kinematics.forward(tr.q)
    assert np.abs(P - tr.P).max() < 1e-9 and np.abs(O - tr.O).max() < 1e-9
    speed = np.linalg.norm(np.diff(tr.P, axis=0), axis=1) / TS
    for corner in corners[1:3]:
        at = int(np.argmin(np.linalg.norm(tr.P - corner, axis=1)))
        assert np.linalg.norm(tr.P[at] - corner) < 1e-9
        assert speed[at - 1:at + 1].max() < 1e-3 * speed.max()   # in and out of it: at rest
    # the source line of the point each sample moves to, stretch by stretch
    assert tr.line[0] == 11 and tr.line[-1] == 14
    assert set(tr.line[(tr.P[:, 0] > 1.0) & (tr.P[:, 1] == 0.0)]) == {12}
    assert set(tr.line[(tr.P[:, 0] == 40.0) & (tr.P[:, 1] > 0.1) & (tr.P[:, 1] < 3.9)]) == {13}


def test_a_corner_at_a_singular_direction_is_refused_naming_its_row(machine):
    """A plunge with the tool along the A-C trunnion's C axis, then a move that tilts it: at
    the corner C is free, and the next stretch starts on another C than the plunge stopped on,
    so the table would have to turn the part at the corner; refused with the corner's row."""
    P = np.array([[10.0, -5.0, 40.0], [10.0, -5.0, 20.0], [12.5, -4.0, 19.5],
                  [15.0, -3.0, 19.0], [17.5, -2.0, 18.5]])
    tilt = np.radians([0.0, 0.0, 10.0, 20.0, 30.0])
    O = np.column_stack([np.sin(tilt), np.zeros(5), np.cos(tilt)])
    with pytest.raises(ToolPathError, match=r"row 2.*singular direction"):
        generate_trajectory(ToolPath(P=P, O=O, source="plunge"), machine)


def test_an_error_in_a_stretch_after_a_corner_names_the_row_of_the_file():
    """A tool path with a corner at row 3 whose second stretch turns the tool by more than a
    right angle between rows 5 and 6: the error names row 6 of the file, not of the stretch."""
    P = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [2, 2, 0], [2, 2.1, 0]])
    O = np.tile([0.0, 0.0, 1.0], (6, 1))
    O[5] = [0.0, -0.6, -0.8]                       # turns by 143 degrees from row 5
    with pytest.raises(ToolPathError, match=r"row 6.*turns by"):
        generate_trajectory(ToolPath(P=P, O=O, source="turn"), load_machine("zhang2013"))
