"""The servo-first API (precontour.system) against the stage functions it calls and against
an independent integration: the same numbers, one way to call them."""

from __future__ import annotations

import numpy as np
import pytest

import precontour
from precontour import (builtin_path, compensate, contour_errors, generate_trajectory,
                        load_machine, load_servo, predict, simulate)
from precontour.compensation.precompensate import compensate as compensate_stage
from precontour.errors import InputError
from precontour.prediction import ReferencePath
from precontour.prediction import contour_errors as contour_errors_stage
from precontour.simulation import simulate as simulate_stage


@pytest.fixture(scope="module")
def servo():
    return load_servo("zhang2013", "pid-high")


@pytest.fixture(scope="module")
def paper(servo):
    return generate_trajectory(builtin_path("paper"), servo.machine)


def test_servo_is_made_once_from_a_name_a_file_or_a_machine(servo, tmp_path):
    machine = load_machine("zhang2013")
    same = load_servo(machine, "pid-high")
    assert same.machine is machine and servo.servo_period == machine.servo_period == 0.001
    assert servo.axis_names == tuple(machine.axis_names)
    for ours, theirs in zip(servo.models, machine.controller("pid-high").error_models(
            machine.drives)):
        np.testing.assert_array_equal(ours.num, theirs.num)
        np.testing.assert_array_equal(ours.den, theirs.den)
    np.testing.assert_array_equal(servo.axis_limits.jerk, [d.j_max for d in machine.drives])
    with pytest.raises(precontour.MachineFileError, match="unknown controller"):
        load_servo("zhang2013", "pid-medium")
    assert "Servo(machine='zhang2013'" in repr(servo)


def test_predict_is_the_closed_form_of_each_axis(servo, paper):
    """The stage's closed form (checked against lsim and solve_ivp in tests/prediction), at
    once for this length; the contour errors come with it where the reference is known."""
    from precontour.prediction import predict_tracking

    predicted = predict(servo, paper)
    stage = predict_tracking(paper.t, paper.q, servo.models)(paper.t)
    assert np.abs(predicted.e - stage).max() <= 1e-12
    assert predicted.contour is not None and predicted.contour.tip.size == paper.n_samples
    without = predict(servo, paper.__class__(t=paper.t, q=paper.q))
    assert without.contour is None


def test_compensate_without_limits_is_the_stage_function(servo, paper):
    ours = compensate(servo, paper, limits=False)
    stage = compensate_stage(servo, paper)
    np.testing.assert_array_equal(ours.commands.q, stage.trajectory.q)
    assert ours.reference is paper and not ours.within_limits and ours.slowdowns == ()
    assert ours.after.tip.max() == stage.after.tip.max()


def test_compensate_keeps_the_limits_by_default(servo):
    circle = generate_trajectory(builtin_path("circle"), servo.machine)
    comp = compensate(servo, circle)
    assert comp.within_limits and comp.slowdowns and comp.added_time > 0
    jerk = np.abs(np.diff(comp.commands.q, 3, axis=0)).max(axis=0) / circle.ts ** 3
    assert np.all(jerk <= servo.axis_limits.jerk * (1 + 1e-9))
    assert comp.reference.n_samples == comp.commands.n_samples > circle.n_samples


def test_simulate_and_contour_errors_are_the_stage_functions(servo, paper):
    comp = compensate(servo, paper, limits=False)
    sim = simulate(servo, comp)
    stage = simulate_stage(paper.t, comp.commands.q, servo.machine, "pid-high",
                           mode="discrete", friction=True, ff_friction=True)
    np.testing.assert_array_equal(sim.q_act, stage.q_act)
    ours = contour_errors(servo, paper, sim)
    theirs = contour_errors_stage(ReferencePath.from_trajectory(paper), stage.q_act,
                                  servo.kinematics)
    np.testing.assert_array_equal(ours.tip, theirs.tip)
    exact = simulate(servo, comp.commands.q, realism="exact")
    assert exact.mode == "continuous"
    # compensation works on both machines
    before = contour_errors(servo, paper, simulate(servo, paper)).tip.max()
    assert ours.tip.max() < 0.2 * before


def test_bad_keywords_are_one_line_errors(servo, paper):
    with pytest.raises(InputError, match="method"):
        compensate(servo, paper, method="magic")
    with pytest.raises(InputError, match="realism"):
        simulate(servo, paper, realism="perfect")
    with pytest.raises(InputError, match="learn"):
        compensate(servo, paper, learn=-1)
    with pytest.raises(InputError, match="reference"):
        compensate(servo, paper.__class__(t=paper.t, q=paper.q))


def test_learning_is_skipped_with_a_notice_where_it_cannot_run(servo, paper, caplog):
    coarse = paper.__class__(t=paper.t[::2], q=paper.q[::2], P=paper.P[::2], O=paper.O[::2])
    comp = compensate(servo, coarse, learn=1)
    assert comp.learning is None
    assert "no learning: the trajectory's sample period 0.002 s" in caplog.text


def test_results_plot_themselves(servo, paper):
    """Compensation.plot() and plot_contour_errors draw what they were given: each line's
    data is the errors in um / mrad, on the reference's times."""
    from precontour import plot_contour_errors

    comp = compensate(servo, paper, limits=False)
    fig = comp.plot()
    tip, ori = fig.axes
    lines = tip.get_lines()
    assert [line.get_label().split(":")[0] for line in lines] == ["uncompensated", "compensated"]
    np.testing.assert_array_equal(lines[1].get_ydata(), 1e3 * comp.after.tip)
    np.testing.assert_array_equal(ori.get_lines()[0].get_xdata(), comp.reference.t)
    fig = plot_contour_errors(servo, paper, {"uncompensated": simulate(servo, paper),
                                             "compensated": simulate(servo, comp)})
    simulated = contour_errors(servo, paper, simulate(servo, comp))
    np.testing.assert_array_equal(fig.axes[1].get_lines()[1].get_ydata(),
                                  1e3 * simulated.orientation)


def test_compensation_has_one_entry_and_the_system_is_the_machines():
    """One public compensation function, the servo first, which the top level and
    precontour.system give too; the servo is the machine stage's; learning's former entry and
    run's former helpers still answer, with a DeprecationWarning naming the release that
    removes them."""
    import precontour.compensation as compensation
    import precontour.workflow as workflow
    from precontour.compensation.stops import learn_at_stops
    from precontour.machine import servo as machine_servo

    functions = [name for name in compensation.__all__
                 if callable(getattr(compensation, name))
                 and not isinstance(getattr(compensation, name), type)]
    assert functions == ["compensate"]
    assert precontour.compensate is compensation.compensate is precontour.system.compensate
    assert precontour.Servo is machine_servo.Servo
    assert precontour.load_servo is machine_servo.load_servo
    with pytest.warns(DeprecationWarning, match="removed in precontour"):
        assert compensation.learn_at_stops is learn_at_stops
    for former in ("compensate_keeping_limits", "learn_on_ensemble"):
        with pytest.warns(DeprecationWarning, match="servo first"):
            assert callable(getattr(workflow, former))
    with pytest.raises(AttributeError):
        compensation.learn_within_limits
    servo = precontour.load_servo("zhang2013", "pid-high")
    with pytest.warns(DeprecationWarning, match="Servo.limits: former spelling"):
        assert servo.limits is servo.axis_limits


def test_the_former_calls_give_what_the_servo_first_ones_give(servo, paper):
    """``workflow.compensate_keeping_limits(traj, machine, controller)`` (former) is the
    limits route of ``compensate(servo, traj)``; the former stage call
    ``compensation.compensate(traj, kinematics, ...)`` is refused in one line that
    names where it went."""
    import precontour.compensation as compensation
    import precontour.workflow as workflow

    with pytest.warns(DeprecationWarning):
        keeping = workflow.compensate_keeping_limits
    limited = keeping(paper, servo.machine, servo.controller)
    np.testing.assert_array_equal(limited.result.trajectory.q,
                                  compensate(servo, paper).commands.q)
    with pytest.raises(InputError, match="servo first.*precompensate.compensate") as error:
        compensation.compensate(paper, servo.kinematics)
    assert "\n" not in str(error.value)


def test_every_job_result_summarises_and_plots_itself(servo, paper, tmp_path):
    """predict, simulate and run give results with summary() and plot(), like compensate's:
    the summaries are the peaks of their own errors, computed here again; the figures draw
    those errors against the results' times."""
    from precontour.machine.drives import TrackingSummary
    from precontour.workflow import run_program

    predicted = predict(servo, paper)
    summary = predicted.summary()
    assert isinstance(summary, TrackingSummary) and summary.axis_names == servo.axis_names
    peak = np.abs(predicted.e).max(axis=0)
    assert summary["X"] == pytest.approx(1e3 * peak[0]) and summary["C"] == \
        pytest.approx(1e6 * peak[4])
    fig = predicted.plot()
    assert len(fig.axes) == 4                      # linear, rotary, tip, orientation
    np.testing.assert_array_equal(fig.axes[0].get_lines()[1].get_ydata(), 1e3 * predicted.e[:, 1])
    np.testing.assert_array_equal(fig.axes[1].get_lines()[0].get_xdata(), paper.t)
    sim = simulate(servo, paper)
    assert sim.summary().max_abs == TrackingSummary.of(paper.q - sim.q_act).max_abs
    assert len(sim.plot().axes) == 2
    program = tmp_path / "paper.csv"
    np.savetxt(program, np.column_stack([paper.P[::50], paper.O[::50]]), delimiter=",",
               header="Px,Py,Pz,Oi,Oj,Ok", comments="")
    result = run_program(program, machine="zhang2013", controller="pid-high", draws=1)
    headline = result.summary()
    assert headline.after == result.simulated_after.summary()
    assert headline.reduction() == pytest.approx(
        1 - result.simulated_after.tip.max() / result.simulated_before.tip.max())
    assert headline.lines_worse == len(result.worse_lines())
    assert result.plot().axes
    assert result.table().startswith("contour errors")


def test_the_gcode_tolerance_has_its_own_name(servo, paper, tmp_path):
    """``gcode_tolerance`` is the G-code decimation's (not the contour tolerance, the corner
    blending's or the fits'): the former ``tolerance=`` still works, warned, and gives the
    same program; both at once are refused in one line."""
    from precontour.tables import write_columns
    from precontour.workflow import export_commands, run_program

    commands = tmp_path / "commands.csv"
    write_columns(commands, {"t": paper.t, **{a: paper.q[:, i] for i, a in
                                             enumerate(servo.axis_names)}})
    coarse = np.array([1e-2] * 3 + [1e-4] * 2)         # ten times the default
    new = export_commands(commands, tmp_path / "new.ngc", machine="zhang2013",
                          gcode_tolerance=coarse)
    with pytest.warns(DeprecationWarning, match="tolerance=: former spelling"):
        old = export_commands(commands, tmp_path / "old.ngc", machine="zhang2013",
                              tolerance=coarse)
    assert old.n_blocks == new.n_blocks < export_commands(
        commands, tmp_path / "fine.ngc", machine="zhang2013").n_blocks
    with pytest.raises(InputError, match="give gcode_tolerance, not tolerance"):
        run_program(tmp_path / "none.ngc", machine="zhang2013", controller="pid-high",
                    gcode_tolerance=coarse, tolerance=coarse)
