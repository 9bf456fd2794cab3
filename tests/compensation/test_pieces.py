"""Programs in pieces: cutting a program (in motion or at a stop) changes the predicted errors
and the compensated commands by far less than the spline fit's tolerance (measured: 1e-12)."""

import numpy as np
import pytest

from conftest import servo_of
from precontour.compensation.pieces import (Piece, compensate_program, contour_errors_program,
                                            overlap_samples, plan_pieces, predict_program,
                                            slowest_decay_rate)
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.trajectory.sampled import Trajectory


@pytest.fixture(scope="module")
def back_and_forth(machine):
    """The paper path forward, backward and forward again: 3 rest-to-rest runs with a 0.2 s
    dwell at each turn, continuous in position."""
    one = generate_trajectory(builtin_path("paper"), machine)
    ts = one.ts
    runs = [one.q, one.q[::-1], one.q]
    P = [one.P, one.P[::-1], one.P]
    O = [one.O, one.O[::-1], one.O]
    q = np.concatenate(runs)
    return Trajectory(np.arange(q.shape[0]) * ts, q, np.concatenate(P), np.concatenate(O))


def test_plan_covers_every_sample_once_and_prefers_stops(back_and_forth):
    traj = back_and_forth
    n = traj.n_samples
    pieces = plan_pieces(n, 500, lambda a, b: traj.q[a:b], piece_samples=2_900, ts=traj.ts)
    kept = np.concatenate([np.arange(p.keep_start, p.keep_stop) for p in pieces])
    np.testing.assert_array_equal(kept, np.arange(n))
    for p in pieces:
        assert p.start % 50 == 0 and max(0, p.keep_start - 549) <= p.start <= max(0, p.keep_start - 500)
        assert p.stop == min(n, p.keep_stop + 500)
    # the first cut is planned at 2,900; the dwell at the end of the first run (samples
    # ~2,570-2,770) is within the last quarter before it, and the cut lands in its middle
    first_run = n // 3
    cut = pieces[0].keep_stop
    assert first_run - 200 < cut < first_run
    assert np.all(np.abs(np.diff(traj.q[cut - 20:cut + 20], axis=0)) < 1e-9)
    # no stop: cut where planned
    assert [p.keep_stop for p in plan_pieces(10_000, 100, piece_samples=4_000)] == [4_000, 10_000]
    assert plan_pieces(5_000, 100, piece_samples=4_000) == [Piece(0, 5_000, 0, 5_000)]


def test_overlap_from_the_slowest_pole(machine):
    models = machine.error_models("pid-low")
    sigma = slowest_decay_rate(models)
    assert 6.0 < sigma < 6.2                              # the PID's slowest pole, -6.1 /s
    one, three = overlap_samples(models, 1e-3, 1), overlap_samples(models, 1e-3, 3)
    # a start-up transient dies to 1e-9 within each chained prediction's share
    assert np.exp(-sigma * (three - one) / 2 * 1e-3) <= 1e-9


@pytest.mark.parametrize("controller", ["pid-high", "pid-low"])
def test_predicting_in_pieces_changes_nothing_beyond_the_fit_tolerance(machine, back_and_forth,
                                                                       controller):
    servo = servo_of(machine, controller)
    traj = back_and_forth
    whole = predict_program(servo, traj)
    # cut in motion (1,000-sample pieces, far from the stops) and at stops
    for piece_samples in (1_000, 2_900):
        cut = predict_program(servo, traj, piece_samples=piece_samples,
                              at_once_samples=0)
        assert cut.pieces >= 3
        scale = 1e-3 * np.array([1e-3] * 3 + [1e-6] * 2)  # 1/1000 of the fit tolerances
        assert np.all(np.abs(cut.e - whole.e).max(axis=0) <= scale)
        assert np.abs(cut.contour.tip - whole.contour.tip).max() <= 1e-6
        assert np.abs(cut.contour.orientation - whole.contour.orientation).max() <= 1e-9


def test_contour_errors_in_pieces_are_those_of_the_whole(machine, back_and_forth):
    # the actual motion of the realistic machine (friction, stick-slip at the turns)
    from precontour.prediction.contour import ReferencePath
    from precontour.simulation.virtual_machine import realistic_actual

    traj = back_and_forth
    q_act = realistic_actual(traj.t, machine, "pid-high")(traj.q)
    whole = ReferencePath.from_trajectory(traj).errors(*machine.kinematics.forward(q_act))
    for piece_samples in (1_000, 2_900):
        cut = contour_errors_program(traj, q_act, machine.kinematics,
                                     piece_samples=piece_samples, at_once_samples=0)
        assert cut.tip.shape == whole.tip.shape
        assert np.abs(cut.tip - whole.tip).max() <= 1e-9
        assert np.abs(cut.orientation - whole.orientation).max() <= 1e-12
        np.testing.assert_allclose(cut.tip_parameter, whole.tip_parameter, rtol=0, atol=1e-9)


def test_compensating_in_pieces_changes_nothing_beyond_the_fit_tolerance(machine,
                                                                         back_and_forth):
    servo = servo_of(machine, "pid-high")
    traj = back_and_forth
    whole = compensate_program(servo, traj, min_passes=1)
    cut = compensate_program(servo, traj, min_passes=1,
                             piece_samples=1_000, at_once_samples=0)
    scale = 1e-3 * np.array([1e-4] * 3 + [1e-7] * 2)     # 1/1000 of the fit tolerances
    assert np.all(np.abs(cut.trajectory.q - whole.trajectory.q).max(axis=0) <= scale)
    assert np.abs(cut.after.tip - whole.after.tip).max() <= 1e-7
    assert cut.after.summary()["tip_max_um"] < 0.2 * cut.before.summary()["tip_max_um"]
