"""Compensation within the machine's limits: slowed where needed, checked with plain finite
differences; impossible limits are errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from precontour.compensation import within_limits
from precontour.compensation.precompensate import compensate
from precontour.compensation.stops import DEFAULT_LEARNING_PASSES
from precontour.compensation.within_limits import compensate_within_limits, learn_within_limits
from precontour.machine.machine_file import load_machine
from precontour.errors import MachineLimitError
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.ensemble import MachineEnsemble, ensemble_actual
from precontour.simulation.virtual_machine import REALISTIC, simulate
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.trajectory.limits import AxisLimits

from conftest import FRICTION_DRAWS, nanometre_draws, servo_of


@pytest.fixture(scope="module")
def circle(machine):
    return generate_trajectory(builtin_path("circle"), machine)


def _peaks(q, ts):
    return [np.abs(np.diff(q, k, axis=0)).max(axis=0) / ts**k for k in (1, 2, 3)]


def test_slows_down_where_compensation_breaks_a_limit(machine, circle):
    limits = AxisLimits.from_machine(machine)
    line = np.arange(circle.n_samples) // 10 + 1
    result = compensate_within_limits(servo_of(machine, "pid-high"), circle, line=line)
    # The first compensation breaks a jerk limit (A and C near the end of the circle).
    assert not result.first_check.ok and result.rounds >= 2
    q = result.result.trajectory.q
    for peak, limit in zip(_peaks(q, circle.ts), (limits.velocity, limits.acceleration,
                                                  limits.jerk)):
        assert np.all(peak <= limit * (1 + 1e-9))
    assert result.slowdowns and result.added_time > 0
    assert result.reference.n_samples == circle.n_samples + round(result.added_time / circle.ts)
    for slow in result.slowdowns:
        assert 0 < slow.speed < 1 and slow.lines[0] <= slow.lines[1]
    # The time map runs through the planned samples, slower where it slowed.
    assert result.planned_index[0] == 0 and result.planned_index[-1] == circle.n_samples - 1
    assert np.all(np.diff(result.planned_index) > 0)
    assert np.all(np.diff(result.line) >= 0)
    # Still compensates: the predicted errors shrink.
    assert result.result.after.tip.max() < 0.2 * result.result.before.tip.max()


def test_within_limits_is_left_alone(machine, circle):
    result = compensate_within_limits(servo_of(machine, "pid-low"), circle)
    assert result.rounds == 1 and result.slowdowns == ()
    assert result.reference is circle


def test_impossible_limits_are_errors(machine, circle):
    limits = AxisLimits.from_machine(machine)
    travel = dataclasses.replace(limits, position_max=np.full(5, 10.0))
    with pytest.raises(MachineLimitError, match="travel"):
        compensate_within_limits(servo_of(machine, "pid-high", travel), circle)
    # the planned commands themselves break these limits: no taper can help
    tight = dataclasses.replace(limits, jerk=limits.jerk * 0.01)
    with pytest.raises(MachineLimitError, match=r"after 1 compensation round\(s\)"):
        compensate_within_limits(servo_of(machine, "pid-high", tight), circle, max_rounds=1)


def test_windows_slowing_cannot_cure_fall_back_to_the_planned_commands(machine, circle):
    first = compensate_within_limits(servo_of(machine, "pid-high"), circle)
    assert first.rounds >= 2 and not first.uncompensated   # slowing alone keeps the limits
    # with no round to slow down in, the windows over a limit keep the planned commands
    once = compensate_within_limits(servo_of(machine, "pid-high"), circle, max_rounds=1)
    assert once.check.ok and once.uncompensated
    t = once.reference.t
    for start, stop in once.uncompensated:
        inside = (t >= start) & (t <= stop)
        middle = inside & (t >= start + 0.15) & (t <= stop - 0.15)
        np.testing.assert_array_equal(once.result.trajectory.q[middle], circle.q[middle])


@pytest.mark.parametrize("path, floor, left_out", [("circle", 0.9, False), ("fan", 0.9, True),
                                                   ("circle", 0.97, True)])
def test_no_window_is_slowed_below_the_floor(machine, path, floor, left_out):
    """Unfloored, circle and fan slow to 77-80 % of their speed (measured); with a floor
    above that, the time map never runs slower than the floor and the limits hold (plain
    finite differences). Where the floor stopped the slowing (circle at 0.9 needed none: its
    retiming margin covered it), the planned commands are kept."""
    traj = generate_trajectory(builtin_path(path), machine)
    limits = AxisLimits.from_machine(machine)
    free = compensate_within_limits(servo_of(machine, "pid-high"), traj, min_speed=0.5)
    assert min(s.speed for s in free.slowdowns) < floor - 0.05
    floored = compensate_within_limits(servo_of(machine, "pid-high"), traj,
                                       min_speed=floor)
    assert np.diff(floored.planned_index).min() >= floor
    assert min(s.speed for s in floored.slowdowns) >= floor
    assert floored.added_time < free.added_time
    q = floored.result.trajectory.q
    for peak, limit in zip(_peaks(q, traj.ts), (limits.velocity, limits.acceleration,
                                                limits.jerk)):
        assert np.all(peak <= limit * (1 + 1e-9))
    assert bool(floored.uncompensated) == left_out and floored.min_speed == floor
    t = floored.reference.t
    for start, stop in floored.uncompensated:
        middle = (t >= start + 0.15) & (t <= stop - 0.15)
        np.testing.assert_array_equal(q[middle], floored.reference.q[middle])


def test_a_floor_of_one_never_slows_and_keeps_the_limits(machine, circle):
    result = compensate_within_limits(servo_of(machine, "pid-high"), circle, min_speed=1.0)
    assert result.slowdowns == () and result.reference.n_samples == circle.n_samples
    assert result.check.ok and result.uncompensated
    with pytest.raises(ValueError, match="min_speed"):
        compensate_within_limits(servo_of(machine, "pid-high"), circle, min_speed=0.0)


def test_splicing_matches_compensating_everything_again(machine, circle):
    spliced = compensate_within_limits(servo_of(machine, "pid-high"), circle, splice=True)
    full = compensate_within_limits(servo_of(machine, "pid-high"), circle, splice=False)
    assert spliced.rounds == full.rounds >= 2
    assert spliced.reference.n_samples == full.reference.n_samples
    dq = np.abs(spliced.result.trajectory.q - full.result.trajectory.q).max(axis=0)
    # Measured 3e-5 mm and 6e-8 rad: the two spline fits' difference, far below the errors.
    assert np.all(dq <= [1e-4] * 3 + [1e-6] * 2), dq
    a, b = spliced.result.after.summary(), full.result.after.summary()
    assert a["tip_max_um"] == pytest.approx(b["tip_max_um"], rel=0.05)
    assert a["ori_max_mrad"] == pytest.approx(b["ori_max_mrad"], rel=0.05)
    assert spliced.result.before.tip.max() == pytest.approx(full.result.before.tip.max())


def test_taper_leaves_the_correction_out_where_it_breaks_a_limit_and_is_smooth():
    from precontour.compensation.blend import TAPER_HOLD, taper_corrections

    ts = 1e-3
    n = 4000
    t = np.arange(n) * ts
    planned = np.column_stack([np.sin(t)] * 5)
    correction = np.full((n, 5), 1e-3)
    correction[2000:, 4] += 1e-4 * (t[2000:] - t[2000])   # a kink in C's correction at 2.0 s
    over = np.zeros(n, dtype=bool)
    over[1999:2002] = True
    q, windows = taper_corrections(planned, planned + correction, over, ts)
    # exactly the planned commands on the samples over the limit and within the hold
    hold = int(round(TAPER_HOLD / ts))
    np.testing.assert_array_equal(q[1999 - hold:2002 + hold], planned[1999 - hold:2002 + hold])
    # untouched far away, and one window reported around the kink
    np.testing.assert_array_equal(q[:1000], (planned + correction)[:1000])
    np.testing.assert_array_equal(q[3200:], (planned + correction)[3200:])
    assert len(windows) == 1 and windows[0][0] < 1999 and windows[0][1] > 2001
    # the taper of a 1 um correction adds a jerk far below the machines' limits: measured 128
    # mm/s^3 (the cubic B-spline's third derivative over 0.1 s), against 12,000 on the
    # LinuxCNC sims and 200,000 on zhang2013
    jerk = np.abs(np.diff(q[:, 0] - planned[:, 0], 3)).max() / ts**3
    assert jerk < 200.0



def _spiral(n_points: int, r0: float = 10.0, r1: float = 15.0):
    """A smooth five-axis CL path in the manner of ``benchmarks/bench_trajectory.py``'s: the
    tool tip spirals over a dome (radius ``r0`` -> ``r1`` mm, 0.1 mm between points) while
    the tool tilts (A 0.3-0.9 rad) and turns with the spiral, C reversing thrice a turn."""
    from precontour.toolpath import ToolPath

    u = np.linspace(0.0, 1.0, n_points)
    turns = 0.1 * n_points / (2 * np.pi * 0.5 * (r0 + r1))
    theta = 2 * np.pi * turns * u
    r = r0 + (r1 - r0) * u
    P = np.stack([r * np.cos(theta), r * np.sin(theta), 30.0 * np.cos(r / 40.0)], axis=-1)
    A = 0.6 + 0.3 * np.sin(7 * theta / turns)
    C = theta + 0.4 * np.sin(3 * theta)
    O = np.stack([np.sin(A) * np.sin(C), -np.sin(A) * np.cos(C), np.cos(A)], axis=-1)
    return ToolPath(P=P, O=O, source="spiral")


def test_rough_corrections_are_smoothed_instead_of_slowed(machine, monkeypatch):
    """Where C reverses on a smooth five-axis path whose reference uses little of the limits,
    the tool axis's contour correction turns within tens of milliseconds and breaks the jerk
    limit. Blended into tracking-error pre-compensation there, the commands keep the limits
    with less slowing (measured: 0.079 s added instead of 0.276 s), and on the linear
    virtual machine (``simulate`` in continuous mode without friction: not the prediction
    that decided) their contour errors in each smoothed window stay within the block margins
    of those of the compensated commands, which break the limit there."""
    from precontour.compensation.blocks import ORIENTATION_MARGIN, TIP_MARGIN, margin_bound

    traj = generate_trajectory(_spiral(6000), machine)
    servo = servo_of(machine, "pid-high")
    limits = AxisLimits.from_machine(machine)
    limited = compensate_within_limits(servo_of(machine, "pid-high"), traj)
    assert not limited.first_check.ok and limited.check.ok and limited.smoothed
    q = limited.result.trajectory.q
    for peak, limit in zip(_peaks(q, traj.ts), (limits.velocity, limits.acceleration,
                                                limits.jerk)):
        assert np.all(peak <= limit * (1 + 1e-9))
    # the compensated commands on the same (final) timing, limits not kept
    reference = limited.reference
    free = compensate(servo, reference).trajectory.q
    path = ReferencePath.from_trajectory(reference)
    errors = {label: contour_errors(path, simulate(reference.t, command, machine, "pid-high",
                                                   mode="continuous", friction=False,
                                                   ff_friction=False).q_act,
                                    machine.kinematics)
              for label, command in (("smoothed", q), ("free", free))}
    assert not np.allclose(q, free)
    # the smoothed windows, in the time of the original reference, on the final one
    original_t = traj.t[0] + limited.planned_index * traj.ts
    for start, stop in limited.smoothed:
        inside = (original_t >= start) & (original_t <= stop)
        assert inside.any()
        smoothed, compensated = errors["smoothed"], errors["free"]
        assert smoothed.tip[inside].max() <= margin_bound(compensated.tip[inside].max(),
                                                          TIP_MARGIN)
        assert smoothed.orientation[inside].max() <= margin_bound(
            compensated.orientation[inside].max(), ORIENTATION_MARGIN)
    # without it, slowing down alone
    monkeypatch.setattr(within_limits, "smooth_instead_of_slowing",
                        lambda servo, reference, q, *args: (q, []))
    slowed = compensate_within_limits(servo_of(machine, "pid-high"), traj)
    assert not slowed.smoothed and slowed.check.ok
    assert limited.added_time < 0.5 * slowed.added_time


def test_a_blend_that_would_leave_the_path_is_slowed_instead(machine, circle):
    """On ``circle`` with pid-high the jerk limit breaks near the end, where the blend into
    tracking-error pre-compensation would leave 2.96 um against the compensated commands'
    0.11 um (predicted): that window is slowed down, not smoothed."""
    result = compensate_within_limits(servo_of(machine, "pid-high"), circle)
    assert not result.first_check.ok and not result.smoothed and result.slowdowns

#: A TCP program whose first feed move starts where a rapid ends, at an angle, and whose
#: last ends before a rapid: at both stops the predicted actual tool tip's closest reference
#: point switches from one leg of the corner to the other.
CORNER_PROGRAM = """G21 G90 G94
G43.4 H0
G0 X0 Y0 Z10 A0 C0
G0 X-5 Y2 Z5 A-20 C-10
G1 X-6 Y3 Z4 F300
G1 X-2 Y3 Z6 A-25 C-5 F150
G1 X4 Y1 Z6 A-30 C10 F150
G1 X8 Y-4 Z5 A-28 C25 F150
G0 Z20
G49
M2
"""


def test_kinks_are_smoothed_instead_of_slowed(tmp_path, monkeypatch):
    from precontour.workflow import load_program_trajectory

    machine = load_machine("linuxcnc-xyzac-trt")
    program = tmp_path / "corner.ngc"
    program.write_text(CORNER_PROGRAM)
    traj, _ = load_program_trajectory(program, machine)
    limits = AxisLimits.from_machine(machine)
    smoothed = compensate_within_limits(servo_of(machine, "pid-high"), traj)
    # the first compensation's corner jumps ask for far more stretch than dynamics would
    assert smoothed.first_check.stretch.max() > within_limits.KINK_STRETCH
    assert smoothed.check.ok and smoothed.kinks
    # and no sample slower than the floor: the room a sample has for slowing counts its
    # neighbours' (before it did not, this program ran at 44.9 % of its planned speed near its
    # start with the floor at 50 %; now the corrections there taper to the planned commands)
    assert np.diff(smoothed.planned_index).min() >= smoothed.min_speed
    assert all(slow.speed >= smoothed.min_speed for slow in smoothed.slowdowns)
    t = smoothed.reference.t
    for start, stop in smoothed.kinks:
        assert 0.0 <= start < stop <= t[-1]
    assert all(a[1] < b[0] for a, b in zip(smoothed.kinks, smoothed.kinks[1:]))
    q = smoothed.result.trajectory.q
    for peak, limit in zip(_peaks(q, traj.ts), (limits.velocity, limits.acceleration,
                                                limits.jerk)):
        assert np.all(peak <= limit * (1 + 1e-9))
    # Slowing the kinks instead (the previous behaviour, with no floor on the slowing)
    # stretched this 9 s program by 8.3 s; smoothing them leaves 0.9 s of slowing for the
    # corrections' dynamics.
    monkeypatch.setattr(within_limits, "KINK_STRETCH", np.inf)
    slowed = compensate_within_limits(servo_of(machine, "pid-high"), traj, min_speed=1e-3)
    assert not slowed.kinks
    assert smoothed.added_time < 0.25 * slowed.added_time
    # and the predicted tip error still falls by most of its size
    before, after = smoothed.result.before.tip.max(), smoothed.result.after.tip.max()
    assert after < 0.35 * before


def _nowhere_worse_on_every_draw(reference, q, machine, controller, ensemble, line=None,
                                 program_margin=0.0):
    """Issue 21 sections 1 and 3, checked independently of the code under test: each draw of
    ``ensemble`` simulated on its own (``simulate`` with the draw's options), the contour
    errors of the uncompensated and of ``q`` compared draw by draw in whole (max and mean,
    tip and orientation) and block by block (each 0.1 s window, or each source line of
    ``line``), the worst draw of ``q`` within the uncompensated command's worst draw plus
    0.1 um / 1 urad or 5 % (plus ``program_margin`` of the uncompensated worst draw's largest
    error over the program). Returns the largest block excess beyond that (<= 0: kept)."""
    path = ReferencePath.from_trajectory(reference)
    n = reference.n_samples
    if line is None:
        edges = list(range(0, n, 100)) + [n]
    else:
        edges = [0] + [k for k in range(1, n) if line[k] != line[k - 1]] + [n]
    worst = {}
    for label, command in (("before", reference.q), ("after", q)):
        tip = np.zeros(len(edges) - 1)
        ori = np.zeros(len(edges) - 1)
        summaries = []
        for options in ensemble.options(n):
            errors = contour_errors(path, simulate(reference.t, command, machine, controller,
                                                   **REALISTIC, **options).q_act,
                                    machine.kinematics)
            summaries.append(errors.summary())
            for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
                tip[k] = max(tip[k], errors.tip[a:b].max())
                ori[k] = max(ori[k], errors.orientation[a:b].max())
        worst[label] = (tip, ori, summaries)
    for before, after in zip(worst["before"][2], worst["after"][2]):
        assert all(after[key] <= before[key] for key in before), (before, after)
    tip0, ori0, _ = worst["before"]
    tip1, ori1, _ = worst["after"]
    tip_margin = np.maximum(np.maximum(1e-4, 0.05 * tip0), program_margin * tip0.max())
    ori_margin = np.maximum(np.maximum(1e-6, 0.05 * ori0), program_margin * ori0.max())
    excess = np.maximum(tip1 - tip0 - tip_margin, 1e2 * (ori1 - ori0 - ori_margin))
    return float(excess.max())


def test_learning_within_limits_keeps_them_and_shrinks_the_max(machine):
    """``run --learn``: on `paper` with pid-high the commands within limits (the linear pass,
    which keeps them there) leave 4.4 um of the 37 um max tip error on the realistic machine;
    learning with smoothed updates on the ensemble of machines keeps every limit (plain finite
    differences) and is nowhere worse than uncompensated on every draw, in whole and in every
    0.1 s window. Where friction holds the axes at the final stop is decided by nanometres:
    taking every choice on one exact machine, what learning left over 30 draws
    (:func:`conftest.nanometre_draws`) was 0.48, 0.51, 1.37 or 1.89 um (at most 0.434 of the
    linear pass's); deciding on the ensemble (:class:`MachineEnsemble`), over 10 draws it
    left 0.489-0.507 um (0.112-0.116 of the linear pass's) with the newest dependency
    versions, and with the oldest allowed ones 0.488-0.612 um on nine draws and 1.97 um
    (0.451) on the sixth; the first five, which this test runs, 0.112-0.116 and 0.112-0.130.
    That 0.451 also came up on the second of them in one CI run with the oldest versions
    (2026-12-03; the same commit passed alone and in a second full run: the last bits of the
    motion differ from run to run there), so the worst of the five is bounded above it, by
    0.6, and their median by 0.2. Unsmoothed learning (``compensate``) breaks the jerk
    limit."""
    servo = servo_of(machine, "pid-high")
    limits = AxisLimits.from_machine(machine)
    ensemble = MachineEnsemble()
    ratios = []
    for draw, path in enumerate(nanometre_draws(builtin_path("paper"))):
        traj = generate_trajectory(path, machine)

        def actual(q):
            return simulate(traj.t, q, machine, "pid-high", **REALISTIC).q_act

        limited = compensate_within_limits(servo_of(machine, "pid-high"), traj)
        learned = learn_within_limits(servo_of(machine, "pid-high"), limited,
                                      ensemble_actual(limited.reference.t, machine, "pid-high",
                                                      ensemble),
                                      DEFAULT_LEARNING_PASSES)
        q = learned.result.trajectory.q
        assert learned.check.ok and learned.result.learning.draws == ensemble.draws
        for peak, limit in zip(_peaks(q, traj.ts), (limits.velocity, limits.acceleration,
                                                    limits.jerk)):
            assert np.all(peak <= limit * (1 + 1e-9))
        reference = ReferencePath.from_trajectory(learned.reference)

        def on_machine(q_cmd):
            return contour_errors(reference, actual(q_cmd), machine.kinematics).summary()

        before, start, after = (on_machine(learned.reference.q),
                                on_machine(limited.result.trajectory.q), on_machine(q))
        assert all(after[key] <= before[key] for key in before)
        ratios.append(after["tip_max_um"] / start["tip_max_um"])
        if draw == 0:
            assert _nowhere_worse_on_every_draw(learned.reference, q, machine, "pid-high",
                                                ensemble) <= 0.0
    assert max(ratios) <= 0.6 and np.median(ratios) <= 0.2, ratios
    unsmoothed = compensate(servo, traj, machine_actual=actual)
    assert np.any(_peaks(unsmoothed.trajectory.q, traj.ts)[2] > limits.jerk)   # the problem


def _circle_pid_low_learned(tmp_path, draws: int = FRICTION_DRAWS):
    """`run --learn 4` on `circle` as CL data with `pid-low`, on ``draws`` nanometre draws of
    its points (:func:`conftest.nanometre_draws`): (draw, result) each."""
    from precontour.workflow import RunOutputs, run_program

    for draw, path in enumerate(nanometre_draws(builtin_path("circle"), draws=draws)):
        source = tmp_path / f"circle{draw}.csv"
        np.savetxt(source, np.column_stack([path.P, path.O]), delimiter=",",
                   header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.17g")
        yield draw, run_program(source, RunOutputs(program=tmp_path / "c.ngc"),
                                machine="zhang2013", controller="pid-low", learn=4)


def test_second_chance_margin_keeps_learning_from_returning_the_uncompensated(machine, tmp_path,
                                                                             monkeypatch):
    """`run --learn 4` on `circle` as CL data with `pid-low` (uncompensated 154 um on the
    worst draw), learning without its variant that holds the resting X: within the block
    margins alone no learned command was nowhere worse (the linear pass 4 urad of 26 worse
    at the start, and every fallback's blend leaving its neighbours 5-12 % worse), so
    learning returned the uncompensated command: 0 % removed (docs/programs.md, before).
    The second chance (1 % of the uncompensated worst draw's largest error) keeps a learned
    command where the block margins alone keep none; checked independently, draw by draw and
    window by window, with the margin it was kept under. Measured on 5 nanometre draws of
    the CL points: all kept "pass 4" with the second chance, its worst draw 2.14-2.22 um
    (0.014 of the uncompensated), hence the bound 0.05."""
    # no variant: the held X is what test_resting_axis_held_... is about
    monkeypatch.setattr(within_limits, "hold_resting_axes", lambda reference, q, tol: q)
    ensemble = MachineEnsemble()
    kept = []
    for draw, result in _circle_pid_low_learned(tmp_path):
        report = result.limited.result.learning
        assert report.chosen != "uncompensated", report.chosen
        kept.append(report.kept["tip_max_um"] / report.uncompensated["tip_max_um"])
        margin = 0.01 if "within 1 %" in report.chosen else 0.0
        if draw == 0:
            assert margin == 0.01, report.chosen     # the case this test is about
            assert _nowhere_worse_on_every_draw(
                result.limited.reference, result.limited.result.trajectory.q, machine,
                "pid-low", ensemble, line=result.limited.line, program_margin=margin) <= 0.0
    assert max(kept) <= 0.05, kept


def test_resting_axis_held_where_its_correction_slips(machine, tmp_path):
    """`run --learn 4` on `circle` as CL data with `pid-low`: X never moves, and the linear
    pass corrects it by up to 1 um (the rotary axes' lag seen at the tool tip). Learned with
    X moving, the command kept (second chance above) left X resting a different micrometre
    off on each draw: its worst draw's mean tip error 11.8 % of the uncompensated, and 15
    rows worse than uncompensated beyond the block margins. Learning also learns the variant
    with X held at its reference (``hold_resting_axes``). Measured on 5 nanometre draws of the
    CL points (3 here): each kept a held command, nowhere worse within the block margins
    alone (checked independently, draw by draw and row by row; with the newest and the oldest
    allowed versions every draw kept "pass 3, resting axes held, then draw 3's update (step
    0.25)"), its worst draw's max 0.82 % and mean 5.03 % of the uncompensated on every input
    draw (4.58 % before the commands ended at the programmed end point), hence the bounds
    0.03 and 0.06. (Before the worst draw's own update, the held commands were worse
    at the start in orientation, and a fallback's taper left 5.9 % of both.)"""
    ensemble = MachineEnsemble()
    for draw, result in _circle_pid_low_learned(tmp_path, draws=3):
        report = result.limited.result.learning
        assert "resting axes held" in report.chosen.split(", fell back")[0], report.chosen
        q = result.limited.result.trajectory.q
        np.testing.assert_array_equal(q[:, 0], result.limited.reference.q[:, 0])
        for key, bound in (("tip_max_um", 0.03), ("tip_mean_um", 0.06)):
            assert report.kept[key] <= bound * report.uncompensated[key], (key, report.kept)
        if draw == 0:
            assert _nowhere_worse_on_every_draw(result.limited.reference, q, machine,
                                                "pid-low", ensemble,
                                                line=result.limited.line) <= 0.0
