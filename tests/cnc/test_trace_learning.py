"""Learning from the machine's traces (precontour.cnc.learn, cnc.run's line rule), checked
against scipy's lsim of the closed loops and an independent closest-point search (a k-d tree on
the reference tip samples)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.spatial import cKDTree

from precontour import builtin_path, generate_trajectory, load_servo
from precontour.cnc import ControllerTrace
from precontour.cnc.learn import align, inverse_model_step, learned_commands, measure_trace
from precontour.cnc.run import worse_lines

PERIOD = 1e-3


@pytest.fixture(scope="module")
def servo():
    return load_servo("zhang2013", "pid-high")


def _loop(servo, commands: np.ndarray) -> np.ndarray:
    """The closed loops x/X = 1 - E(s) of ``servo`` run on ``commands`` by scipy's lsim,
    starting at rest at the first command."""
    t = np.arange(commands.shape[0]) * PERIOD
    actual = np.empty_like(commands)
    for axis, model in enumerate(servo.models):
        num = np.polysub(model.den, model.num)
        start = commands[0, axis]
        _, y, _ = signal.lsim((num, model.den), commands[:, axis] - start, t)
        actual[:, axis] = y + start
    return actual


def test_the_inverse_model_step_undoes_the_loop(servo):
    t = np.arange(2000) * PERIOD
    bump = 10e-3 * np.exp(-0.5 * ((t - 1.0) / 0.04) ** 2)
    wanted = np.column_stack([bump, -bump, 0.5 * bump, 1e-3 * bump, -2e-3 * bump])
    step = inverse_model_step(servo, wanted, PERIOD)
    scale = np.abs(wanted).max(axis=0)
    # measured: 0.26-0.29 % of the bump left on every axis; the loop alone leaves 2.7-3.0 %
    assert np.all(np.abs(_loop(servo, step) - wanted).max(axis=0) < 0.005 * scale)
    assert np.all(np.abs(_loop(servo, wanted) - wanted).max(axis=0) > 0.02 * scale)


def _program_trace(servo, *, block=20):
    traj = generate_trajectory(builtin_path("paper"), servo.machine)
    q = traj.q
    line = 100 + np.arange(q.shape[0]) // block
    return ControllerTrace(t=traj.t, command=q, line=line, source="paper"), np.unique(line)


def _tip_errors(servo, reference: ControllerTrace, actual: np.ndarray) -> np.ndarray:
    """Distance of each actual tip to the reference tip polyline (k-d tree, then the two
    segments beside the nearest sample)."""
    P_ref, _ = servo.kinematics.forward(reference.command)
    P, _ = servo.kinematics.forward(actual)
    _, i = cKDTree(P_ref).query(P)
    best = np.full(P.shape[0], np.inf)
    for offset in (-1, 0):
        j = np.clip(i + offset, 0, P_ref.shape[0] - 2)
        a, v = P_ref[j], P_ref[j + 1] - P_ref[j]
        u = np.clip(np.einsum("ij,ij->i", P - a, v) / np.einsum("ij,ij->i", v, v), 0, 1)
        best = np.minimum(best, np.linalg.norm(a + u[:, None] * v - P, axis=1))
    return best


def test_learning_from_a_trace_removes_the_loops_contour_error(servo):
    reference, lines = _program_trace(servo)
    actual = _loop(servo, reference.command)
    before = _tip_errors(servo, reference, actual)
    run = ControllerTrace(t=reference.t, command=reference.command, actual=actual,
                          line=reference.line, source="run 0")
    commands, measured = learned_commands(servo, reference, run, lines)
    assert measured.summary().tip_max_um == pytest.approx(1e3 * before.max(), rel=0.02)
    after = _tip_errors(servo, reference, _loop(servo, commands))
    # measured: 38.0 -> 0.73 um max, 6.58 -> 0.025 um mean in one step
    assert after.max() < 0.1 * before.max()
    assert after.mean() < 0.05 * before.mean()


def test_align_maps_each_sample_to_the_same_point_of_the_program():
    t = np.arange(300) * PERIOD
    command = np.column_stack([t, 0 * t, 0 * t, 0 * t, 0 * t])
    line = 10 + np.arange(300) // 30
    reference = ControllerTrace(t=t, command=command, line=line)
    # the same run with a hold of 7 periods inserted before block 15 and the first block
    # started 4 periods later
    hold = 150                                # block 15's start
    later = np.concatenate([np.zeros((4, 5)), command[:hold], np.repeat(command[hold - 1:hold],
                                                                        7, axis=0),
                            command[hold:]])
    later_line = np.concatenate([np.full(4, 9), line[:hold], np.full(7, line[hold - 1]),
                                 line[hold:]])
    run = ControllerTrace(t=np.arange(later.shape[0]) * PERIOD, command=later,
                          line=later_line)
    position = align(reference, run, np.unique(line))
    assert position[:hold - 29] == pytest.approx(np.arange(hold - 29) + 4)
    assert position[hold:] == pytest.approx(np.arange(hold, 300) + 11)


def test_a_line_is_worse_beyond_the_margins_or_the_repeatability(servo):
    reference, lines = _program_trace(servo)
    actual = _loop(servo, reference.command)
    base = ControllerTrace(t=reference.t, command=reference.command, actual=actual,
                           line=reference.line)
    worse = actual.copy()
    on = reference.line == lines[40]
    worse[on, 1] += 3e-3                      # 3 um more on one line's Y
    run = ControllerTrace(t=reference.t, command=reference.command, actual=worse,
                          line=reference.line)
    a = measure_trace(servo, reference, base, lines)
    b = measure_trace(servo, reference, run, lines)
    assert worse_lines(b, a) == [int(lines[40])]
    assert worse_lines(a, a) == []
    # a second uncompensated run that scatters as much on that line forgives it
    assert worse_lines(b, a, repeat=b) == []
