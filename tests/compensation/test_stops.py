import numpy as np
import pytest

from precontour.compensation.precompensate import compensate
import precontour.compensation.precompensate as precompensate
from precontour.compensation.blocks import score
from precontour.compensation.stops import (LINE_SEARCH_STEPS, SETTLE_DELAYS, LearningSettings,
                                           final_rest_index, learn_at_stops,
                                           settle_final_dwell)
from precontour.prediction.contour import ContourErrors
from precontour.simulation.ensemble import ensemble_actual
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.virtual_machine import simulate
from precontour.toolpath import ToolPath
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory

from conftest import nanometre_draws, servo_of

REALISTIC = dict(mode="discrete", friction=True, ff_friction=True)


def test_final_rest_index_by_hand():
    q = np.zeros((6, 5))
    q[:3, 0] = [0.0, 1.0, 2.0]
    q[3:, 0] = 3.0
    assert final_rest_index(q) == 3            # q[3:] all equal q[-1]
    q[-1, 4] = 1e-12
    assert final_rest_index(q) is None         # still moving at the last sample
    assert final_rest_index(np.ones((4, 5))) == 0


def test_settle_final_dwell_holds_the_end_and_keeps_the_input():
    q_ref = np.repeat(np.linspace(0, 1, 8)[:, None], 5, axis=1)
    q = q_ref + 0.01
    settled = settle_final_dwell(q, q_ref, 5)
    assert np.array_equal(settled[:5], q[:5])
    assert np.all(settled[5:] == q_ref[-1])
    assert np.all(q[5:] != q_ref[-1])          # the input is not modified


def _fan_like(n_points=25):
    """A short fan-like sweep whose tip reverses in x and whose tool still turns at the end."""
    u = np.linspace(0.0, 1.0, n_points)
    P = np.stack([15.0 * np.sin(np.pi * u), 40.0 * u - 20.0, np.zeros_like(u)], axis=1)
    beta = 0.4 * np.sin(1.75 * np.pi * u)
    O = np.stack([np.full_like(u, np.sin(0.1)), np.sin(beta), np.cos(beta)], axis=1)
    return ToolPath(P=P, O=O / np.linalg.norm(O, axis=1, keepdims=True))


@pytest.fixture(scope="module")
def fan_like(machine):
    return generate_trajectory(_fan_like(), machine, dwell=0.15)


def test_a_machine_that_punishes_every_correction_gets_the_uncompensated_command(machine,
                                                                                   fan_like):
    """Never worse: on a (made-up) machine whose actual motion moves away from the reference
    by five times whatever the command changes, every compensated candidate is worse than the
    reference command, so the reference command is kept."""
    servo = servo_of(machine, "pid-high")

    def punishing(q):
        return fan_like.q - 5.0 * (q - fan_like.q)

    result = compensate(servo, fan_like, machine_actual=punishing,
                        learning_passes=1)
    assert result.learning.chosen == "uncompensated"
    assert result.iterations == 0
    assert np.array_equal(result.trajectory.q, fan_like.q)
    assert all(not c.accepted for c in result.learning.candidates[1:])


def test_learning_counts_machine_runs_and_reports_what_it_kept(machine, fan_like):
    servo = servo_of(machine, "pid-high")
    calls = []

    def actual(q):
        calls.append(1)
        return simulate(fan_like.t, q, machine, "pid-high", **REALISTIC).q_act

    passes = 2
    result = compensate(servo, fan_like, machine_actual=actual,
                        learning_passes=passes)
    report = result.learning
    # reference, then per iterate of the plain sequence (linear + passes) itself and its
    # settled tails, plus the machine run of the orientation-corrected command inside each
    # pass; per line-searched pass that run, one per step tried and the best step's tails
    # (and the judgements of the local fallbacks, if any). While the line search has taken
    # the whole step at every pass, its whole step is the plain iterate: neither its update
    # nor its judgement runs again, and its tails are the plain iterate's.
    settles, steps = len(SETTLE_DELAYS), len(LINE_SEARCH_STEPS)
    searched = [c.label for c in report.candidates if c.label.startswith("line-searched pass")]
    off_track = sum("settled" in label for label in searched) // settles
    reused = min(passes - off_track + 1, passes)
    candidates = 1 + (passes + 1) * (1 + settles) + passes * steps + off_track * settles
    assert report.machine_runs == len(calls) == (candidates - reused + 2 * passes - reused
                                                 + report.fallback_runs)
    assert len(report.candidates) == candidates and report.draws == 1
    assert len(searched) == passes * steps + off_track * settles
    # the kept command, re-run independently, has the reported errors
    reference = ReferencePath.from_trajectory(fan_like)
    rerun = contour_errors(reference, simulate(fan_like.t, result.trajectory.q, machine,
                                               "pid-high", **REALISTIC).q_act,
                           machine.kinematics).summary()
    for key, value in report.kept.items():
        assert rerun[key] == pytest.approx(value, rel=1e-9)
        assert value <= report.uncompensated[key]          # nowhere worse
    # nothing that needed no fallback scores better than what was kept
    assert all(score(report.kept) <= score(c.summary) for c in report.candidates
               if c.accepted and c.blocks_ok)


def test_learning_removes_the_final_stop_error_on_the_fan_path(machine):
    """Issue 13: with pid-high on the realistic machine, one linear pass leaves 20 um of the
    fan path's 52 um at the final stop (0.34 of it); learning against the ensemble of
    machines removes >= 85 %. Over 10 draws (:func:`conftest.nanometre_draws`) it kept
    0.055-0.089 of the max (deciding on the realistic machine alone, 0.056-0.102), so the
    worst of :data:`conftest.FRICTION_DRAWS` is asserted <= 0.15."""
    servo = servo_of(machine, "pid-high")
    for path in nanometre_draws(builtin_path("fan")):
        traj = generate_trajectory(path, machine)

        def actual(q):
            return simulate(traj.t, q, machine, "pid-high", **REALISTIC).q_act

        linear = compensate(servo, traj)
        learned = compensate(servo, traj,
                             machine_actual=ensemble_actual(traj.t, machine, "pid-high"))
        reference = ReferencePath.from_trajectory(traj)

        def tip_max(q):
            return contour_errors(reference, actual(q), machine.kinematics).tip.max()

        before = tip_max(traj.q)
        assert tip_max(linear.trajectory.q) > 0.3 * before          # the problem
        assert tip_max(learned.trajectory.q) <= 0.15 * before       # solved


def test_learning_passes_must_not_be_negative(machine, fan_like):
    with pytest.raises(ValueError, match="learning passes"):
        learn_at_stops(fan_like.q, fan_like.q, fan_like.ts, lambda q: q, None, None, passes=-1)


def _tilted(tilt_x, tilt_y):
    """Unit tool orientations tilted about x, then y (as the test paths of
    scripts/measure_compensation.py)."""
    O = np.stack([np.sin(tilt_y), np.sin(tilt_x) * np.cos(tilt_y),
                  np.cos(tilt_x) * np.cos(tilt_y)], axis=1)
    return O / np.linalg.norm(O, axis=1, keepdims=True)


def _fan25():
    """The test path `fan25` of scripts/measure_compensation.py: 25 points, the tip goes out
    and back in x (a reversal mid-path) along y, the tool fans about x to 0.5 rad and back
    through vertical and ends while still turning."""
    u = np.linspace(0.0, 1.0, 25)
    P = np.stack([20.0 * np.sin(np.pi * u), 60.0 * u - 30.0, 4.0 * np.sin(2 * np.pi * u)], axis=1)
    return ToolPath(P=P, O=_tilted(0.5 * np.sin(1.75 * np.pi * u), 0.1 + 0.15 * u))


def _fan_reversals():
    """A smaller, flat fan (25 points) whose largest errors after learning sit at interior
    reversals: X reverses at 0.42, 0.65, 1.27, 1.47 s, Y, Z, A near 0.55 and 0.97 s."""
    u = np.linspace(0.0, 1.0, 25)
    P = np.stack([15.0 * np.sin(np.pi * u), 40.0 * u - 20.0, np.zeros_like(u)], axis=1)
    return ToolPath(P=P, O=_tilted(0.4 * np.sin(1.75 * np.pi * u), 0.1 + 0.15 * u))


def _learned_and_reference_errors(traj, machine, monkeypatch=None, **learning_options):
    """Contour errors on the realistic machine (pid-high) of the uncompensated command and of
    the command learning on the ensemble of machines keeps (``learning_options`` passed on to
    the learning's settings, :class:`~precontour.compensation.stops.LearningSettings`)."""
    if learning_options:
        def settings(**kwargs):
            return LearningSettings(**kwargs, **learning_options)
        monkeypatch.setattr(precompensate, "LearningSettings", settings)
    servo = servo_of(machine, "pid-high")

    def actual(q):
        return simulate(traj.t, q, machine, "pid-high", **REALISTIC).q_act

    learned = compensate(servo, traj,
                         machine_actual=ensemble_actual(traj.t, machine, "pid-high"))
    reference = ReferencePath.from_trajectory(traj)
    return (contour_errors(reference, actual(traj.q), machine.kinematics),
            contour_errors(reference, actual(learned.trajectory.q), machine.kinematics))


def test_learning_removes_85_percent_at_the_final_stop_of_fan25(machine):
    """Issue 13: >= 85 % of the max tip error removed with pid-high on a path whose tool still
    turns at the final stop, where static friction holds the axes off the end point through
    the dwell (with settling at 0 / 30 / 60 ms only: 82.3 %), and never worse anywhere. Over
    10 draws (:func:`conftest.nanometre_draws`) learning on the ensemble of machines kept
    0.062-0.101 of the max (on the realistic machine alone, 0.062-0.129); the worst of
    :data:`conftest.FRICTION_DRAWS` is asserted."""
    for path in nanometre_draws(_fan25()):
        traj = generate_trajectory(path, machine)
        before, after = _learned_and_reference_errors(traj, machine)
        assert after.tip.max() <= 0.15 * before.tip.max()
        for key, value in after.summary().items():
            assert value <= before.summary()[key]


def test_the_line_search_damps_the_overshoot_at_interior_reversals(machine, monkeypatch):
    """With pid-high the plain learning update overshoots at this path's interior reversals
    and keeps 21 % of the max tip error (at 0.98 s); the line-searched sequence keeps far
    less, never worse anywhere. Over 10 draws (:func:`conftest.nanometre_draws`), learning on
    the ensemble of machines, the plain sequence alone kept 0.205-0.206 on every draw; with
    the line search 0.0885 on 8 of them and 0.149 and 0.154 on two (issue 13's 85 % missed
    there; on the realistic machine alone 0.089-0.136), and with the worst draw's own update
    too 0.078 on 4, 0.0885 on 4, 0.136 and 0.157 on two (oldest allowed versions: at most
    0.136); the worst of :data:`conftest.FRICTION_DRAWS` (0.157) is asserted <= 0.17, the
    plain sequence's > 0.15."""
    for path in nanometre_draws(_fan_reversals()):
        traj = generate_trajectory(path, machine)
        before, plain = _learned_and_reference_errors(traj, machine, monkeypatch,
                                                      line_search_steps=(),
                                                      worst_draw_steps=())
        assert plain.tip.max() > 0.15 * before.tip.max()                 # the problem
        monkeypatch.undo()
        before, after = _learned_and_reference_errors(traj, machine)
        assert after.tip.max() <= 0.17 * before.tip.max()                # solved
        for key, value in after.summary().items():
            assert value <= before.summary()[key]


def test_commands_refused_as_inadmissible_are_not_kept(machine, fan_like):
    """With an admissibility check that refuses every command, learning keeps the
    uncompensated one, however good the others are on the machine."""
    def actual(q):
        return simulate(fan_like.t, q, machine, "pid-high", **REALISTIC).q_act

    reference = ReferencePath.from_trajectory(fan_like)

    def errors_of(q_act):
        return contour_errors(reference, q_act, machine.kinematics)

    servo = servo_of(machine, "pid-high")

    linear = compensate(servo, fan_like).trajectory.q
    q, report = learn_at_stops(fan_like.q, linear, fan_like.ts, actual, errors_of,
                               precompensate.learning_step(fan_like, reference,
                                                           machine.kinematics),
                               passes=1, admissible=lambda q: False)
    assert report.chosen == "uncompensated" and q is fan_like.q
    assert report.linear["tip_max_um"] < report.uncompensated["tip_max_um"]
    assert not any(c.accepted for c in report.candidates[1:])


def _toy_errors(q_act):
    """Contour errors of a toy path along which only X matters: the tip error is |X|."""
    tip = np.abs(q_act[:, 0])
    return ContourErrors(tip=tip, orientation=np.zeros_like(tip),
                         tip_parameter=np.zeros_like(tip),
                         orientation_parameter=np.zeros_like(tip))


def _toy_commands(x_linear: float) -> tuple[np.ndarray, np.ndarray]:
    """A toy reference resting 10 um off in X (400 samples) and a linear command resting
    ``x_linear`` (mm) off."""
    q_ref = np.zeros((400, 5))
    q_ref[:, 0] = 10e-3
    q_linear = np.zeros((400, 5))
    q_linear[:, 0] = x_linear
    return q_ref, q_linear


def test_the_command_kept_is_the_one_whose_worst_draw_is_best():
    """Two draws of a toy machine, the second 4 um off in X: the linear command (2 um; 6 um
    on the second draw) is best on the first draw, the learned one (2.5 um; 1.5 um) on its
    worst draw. With both draws the learned one is kept, with the first alone the linear."""
    q_ref, q_linear = _toy_commands(2e-3)
    q_learned = np.zeros_like(q_ref)
    q_learned[:, 0] = -2.5e-3

    def two_draws(q):
        return np.stack([q, q + np.array([4e-3, 0, 0, 0, 0])])

    def step(q_cmd, q_act, actual):
        return q_learned

    options = dict(passes=1, settle_delays=(), line_search_steps=(), worst_draw_steps=())
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step, **options)
    assert q is q_learned and report.chosen == "pass 1" and report.draws == 2
    assert report.kept["tip_max_um"] == pytest.approx(2.5)
    assert [d["tip_max_um"] for d in report.kept_draws] == pytest.approx([2.5, 1.5])
    assert report.kept_median["tip_max_um"] == pytest.approx(2.0)
    assert report.machine_runs == 2 * 3
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, lambda q: two_draws(q)[0], _toy_errors,
                               step, **options)
    assert q is q_linear and report.chosen == "linear" and report.draws == 1


def test_the_worst_draws_own_update_is_tried_and_kept_where_its_worst_draw_is_best():
    """Two draws of a toy machine, the second answering 2 x + 1 um to a command x (a gain and
    an offset the model does not have), the update x - x_actual. Learned from the draws' mean
    motion, pass 1 (x = -1.5 um) leaves 1.5 and 2 um. A quarter of the update learned from the
    worst draw alone moves to x = -1 um: 1 um on both, so it is kept. The motion its update
    learns from is run on the machine model's one-draw model where it has one, on every draw
    otherwise. With a single machine there is no such update."""
    q_ref, q_linear = _toy_commands(2e-3)
    one_draw_runs = []

    def two_draws(q):
        return np.stack([q, 2 * q + np.array([1e-3, 0, 0, 0, 0])])

    def draw(q, index):
        one_draw_runs.append(index)
        return two_draws(q)[index]

    def step(q_cmd, q_act, actual):
        return q_cmd - q_act

    options = dict(passes=1, settle_delays=(), line_search_steps=())
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step, **options)
    assert report.chosen == "pass 1, then draw 1's update (step 0.25)"
    np.testing.assert_allclose(q[:, 0], -1e-3, rtol=1e-12)
    assert [d["tip_max_um"] for d in report.kept_draws] == pytest.approx([1.0, 1.0])
    # uncompensated, linear, pass 1, the refined command: 2 draws each; the motion of pass 1
    # its update learns from (this toy update runs no other command)
    assert report.machine_runs == 2 * 4 + 2
    two_draws.draw = draw
    q_again, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step,
                                     **options)
    np.testing.assert_array_equal(q_again, q)
    assert one_draw_runs == [1] and report.machine_runs == 2 * 4 + 1
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, lambda q: two_draws(q)[1], _toy_errors,
                               step, **options)
    assert "then draw" not in " ".join(c.label for c in report.candidates)


def test_the_worst_draws_update_keeps_its_origins_variant_and_settled_tail():
    """The toy machine above, where X matters until sample 100 and must then rest at the
    reference's 10 um, and a command that moves Y makes the second draw 4 um worse in X: the
    best command before the worst draw's update is a held and settled one, and the update
    from it keeps Y held and its tail settled (both exactly), and is kept as it is."""
    q_ref, q_linear = _toy_commands(2e-3)
    q_linear[:, 1] = 1e-6
    early = np.arange(400) < 100

    def errors_of(q_act):
        return _toy_errors(np.where(early[:, None], q_act, q_act - q_ref))

    def two_draws(q):
        second = q + np.where(early[:, None], q + np.array([1e-3, 0, 0, 0, 0]), 0.0)
        if np.any(q[:, 1] != q_ref[:, 1]):
            second[:, 0] += 4e-3
        return np.stack([q, second])

    def step(q_cmd, q_act, actual):     # learns X early on, moves Y and the tail's X
        return (q_cmd + [0, 1e-6, 0, 0, 0]
                - np.where(early[:, None], q_act * [1, 0, 0, 0, 0], [-1e-3, 0, 0, 0, 0]))

    def hold_y(q):
        held = q.copy()
        held[:, 1] = q_ref[:, 1]
        return held

    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, errors_of, step, passes=1,
                               settle_delays=(0.1,), line_search_steps=(),
                               variants=(("Y held", hold_y),))
    assert report.chosen.endswith(", Y held, then draw 1's update (step 0.25)"), report.chosen
    assert "settled 100 ms" in report.chosen
    np.testing.assert_array_equal(q[:, 1], q_ref[:, 1])
    np.testing.assert_array_equal(q[100:], np.broadcast_to(q_ref[-1], (300, 5)))
    assert report.fallback is None


def test_a_diverging_update_is_not_kept_and_raises_nothing():
    """A learning update that is not finite, or whose motion on the machine is not, is not
    kept, and nothing learns from it; the machine is never run on a non-finite command."""
    q_ref, q_linear = _toy_commands(2e-3)
    ran = []

    def machine(q):
        assert np.all(np.isfinite(q))
        ran.append(1)
        return np.full_like(q, np.inf) if q[0, 0] < 0 else q

    def diverging(q_cmd, q_act, actual):
        return np.full_like(q_cmd, np.nan)

    q, report = learn_at_stops(q_ref, q_linear, 1e-3, machine, _toy_errors, diverging,
                               passes=3, settle_delays=())
    assert q is q_linear and report.chosen == "linear"
    assert [c.label for c in report.candidates] == ["uncompensated", "linear"]
    assert len(ran) == 2            # the reference and the linear command only

    def to_infinity(q_cmd, q_act, actual):
        return -q_cmd               # its motion is not finite

    q, report = learn_at_stops(q_ref, q_linear, 1e-3, machine, _toy_errors, to_infinity,
                               passes=2, settle_delays=(), line_search_steps=())
    assert q is q_linear and [(c.label, c.accepted) for c in report.candidates] == [
        ("uncompensated", True), ("linear", True), ("pass 1 (diverged)", False)]


def test_a_command_worse_in_whole_on_one_draw_is_repaired_where_it_hurts():
    """A linear command that removes the error everywhere but in its last 0.1 s block, where
    one of two draws leaves 20 um against the uncompensated 10 um (so its whole max is worse on
    that draw, and it is not admissible as it stands), falls back there to the planned command
    and is kept: the whole max equals the uncompensated one (the block that fell back), the
    mean is far below it, and no block is worse. Before, such a command was never repaired
    and the uncompensated one came back."""
    q_ref, q_linear = _toy_commands(1e-3)
    q_linear[300:, 0] = 12e-3

    def two_draws(q):
        second = q.copy()
        second[300:, 0] += np.where(q[300:, 0] > 11e-3, 8e-3, 0.0)
        return np.stack([q, second])

    def step(q_cmd, q_act, actual):
        return q_cmd

    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step, passes=0,
                               settle_delays=(), line_search_steps=())
    assert not report.candidates[1].accepted and report.candidates[1].repairable
    assert report.chosen == "linear, fell back in 1 block(s)"
    assert report.fallback is not None and len(report.fallback.blocks) == 1
    assert report.fallback.blocks[0].start == pytest.approx(0.3)
    changed = np.flatnonzero(np.any(q != q_linear, axis=1))
    assert changed[0] >= 100      # the C2 blend starts within the hold and taper before it
    np.testing.assert_array_equal(q[300:], q_ref[300:])   # the planned command, exactly
    for kept, reference in zip(report.kept_draws, report.uncompensated_draws):
        assert kept["tip_max_um"] <= reference["tip_max_um"]
        assert kept["tip_mean_um"] < 0.6 * reference["tip_mean_um"]


def test_a_block_within_the_uncompensated_repeatability_is_not_worse():
    """The machine run again (``repeat_actual``) changes the uncompensated command's error in
    its last block by 3 um: a linear command 2 um worse there than the uncompensated command
    is kept as it is, nowhere worse; without the rerun it falls back there. The rerun costs
    one run of the draws, counted."""
    q_ref, q_linear = _toy_commands(1e-3)
    q_ref[300:, 0] = 1e-3
    q_linear[300:, 0] = 3e-3

    def again(q):
        moved = q.copy()
        moved[300:, 0] += 3e-3
        return np.stack([q, moved])

    def machine(q):
        return np.stack([q, q])

    options = dict(passes=0, settle_delays=(), line_search_steps=())
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, machine, _toy_errors,
                               lambda q_cmd, q_act, actual: q_cmd, repeat_actual=again,
                               **options)
    assert q is q_linear and report.chosen == "linear" and report.fallback is None
    assert report.machine_runs == 2 * 3
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, machine, _toy_errors,
                               lambda q_cmd, q_act, actual: q_cmd, **options)
    assert report.chosen == "linear, fell back in 1 block(s)"
    assert report.fallback.blocks[0].start == pytest.approx(0.3)


def _slipping_y(q_ref):
    """A toy machine of two draws on which a command that moves the resting axis Y at all
    slips 4 um in X on the second (a resting axis under static friction, pushed by the
    feed-forward), the commands it ran (``tried``), an update that moves Y by 1 nm, and the
    projection holding Y at ``q_ref`` (the same array where it already does)."""
    tried = []

    def two_draws(q):
        tried.append(q)
        second = q.copy()
        if np.any(q[:, 1] != q_ref[:, 1]):
            second[:, 0] += 4e-3
        return np.stack([q, second])

    def step(q_cmd, q_act, actual):
        return q_cmd + np.array([0, 1e-6, 0, 0, 0])    # the update moves Y

    def hold_y(q):
        if np.array_equal(q[:, 1], q_ref[:, 1]):
            return q
        held = q.copy()
        held[:, 1] = q_ref[:, 1]
        return held

    return tried, two_draws, step, hold_y


def test_a_variant_is_learned_again_and_competes_for_being_kept():
    """A toy machine on which a command that moves the resting axis Y at all slips 4 um in X on
    its second draw (a resting axis under static friction, pushed by the feed-forward): the
    linear command (1 um, Y corrected by 1 nm) leaves 5 um on that draw. Its variant with Y
    held, learned again from the held linear command, leaves 1 um on both draws and is kept,
    labelled with the variant's name; every iterate of the variant holds Y. A variant that
    changes nothing learns nothing again."""
    q_ref, q_linear = _toy_commands(1e-3)
    q_linear[:, 1] = 1e-6
    tried, two_draws, step, hold_y = _slipping_y(q_ref)
    options = dict(passes=1, settle_delays=(), line_search_steps=(), worst_draw_steps=())
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step,
                               variants=(("Y held", hold_y),), **options)
    labels = [c.label for c in report.candidates]
    assert labels == ["uncompensated", "linear", "pass 1", "linear, Y held", "pass 1, Y held"]
    assert report.chosen == "linear, Y held"          # the first of the two ties
    np.testing.assert_array_equal(q, hold_y(q_linear))
    assert report.kept["tip_max_um"] == pytest.approx(1.0)
    assert report.linear["tip_max_um"] == pytest.approx(5.0)
    assert report.machine_runs == 2 * 5
    assert all(np.array_equal(q[:, 1], q_ref[:, 1]) for q in tried[-2:])
    q, report = learn_at_stops(q_ref, hold_y(q_linear), 1e-3, two_draws, _toy_errors,
                               lambda q_cmd, q_act, actual: q_cmd,
                               variants=(("Y held", hold_y),), **options)
    assert [c.label for c in report.candidates] == ["uncompensated", "linear", "pass 1"]


def test_a_variant_that_holds_what_only_the_updates_move_is_learned_from_the_linear_motion():
    """The linear command already holds the resting axis Y, but the update moves Y again (it
    learns from every axis's motion): the variant with Y held is learned all the same, from
    the linear command's judgement and motion (not run again, no second "linear" candidate),
    and its pass, which holds Y, leaves 1 um where the plain pass slips to 5 um on the second
    draw. Before, a variant whose projection left the linear command as it was was skipped,
    and the Y-moving passes were the only ones learned (on `circle` / `pid-high`, X slipped
    44 um on one draw)."""
    q_ref, q_linear = _toy_commands(1e-3)
    tried, two_draws, step, hold_y = _slipping_y(q_ref)
    q, report = learn_at_stops(q_ref, q_linear, 1e-3, two_draws, _toy_errors, step,
                               variants=(("Y held", hold_y),), passes=2, settle_delays=(),
                               line_search_steps=(), worst_draw_steps=())
    summaries = {c.label: c.summary["tip_max_um"] for c in report.candidates}
    assert list(summaries) == ["uncompensated", "linear", "pass 1", "pass 2",
                               "pass 1, Y held", "pass 2, Y held"]
    assert summaries["pass 1"] == pytest.approx(5.0)
    assert summaries["pass 1, Y held"] == pytest.approx(1.0)
    assert report.machine_runs == 2 * 6         # the linear command run once
    assert all(np.array_equal(q[:, 1], q_ref[:, 1]) for q in tried[-2:])
    assert report.kept["tip_max_um"] == pytest.approx(1.0)


def test_the_line_search_on_the_plain_track_does_not_run_the_plain_iterate_again():
    """A toy update that halves X's error: the whole step is better at every pass, so the
    line-searched sequence stays on the plain one, and its whole steps are the plain iterates
    themselves (the same arrays, the same judgements) with no machine run: 1 (reference) +
    1 (linear) + 3 (plain passes) + 3 (half steps) runs for 11 candidates."""
    q_ref, q_linear = _toy_commands(4e-3)
    runs = []

    def machine(q):
        runs.append(q)
        return q

    def halve(q_cmd, q_act, actual):
        return 0.5 * q_cmd

    q, report = learn_at_stops(q_ref, q_linear, 1e-3, machine, _toy_errors, halve, passes=3,
                               settle_delays=(), line_search_steps=(0.5, 1.0))
    labels = [c.label for c in report.candidates]
    assert len(runs) == report.machine_runs == 8 and len(labels) == 11
    for k in (1, 2, 3):
        plain = report.candidates[labels.index(f"pass {k}")]
        whole = report.candidates[labels.index(f"line-searched pass {k} (step 1)")]
        assert whole.summary == plain.summary == {"tip_max_um": pytest.approx(4 / 2 ** k),
                                                  "tip_mean_um": pytest.approx(4 / 2 ** k),
                                                  "ori_max_mrad": 0.0, "ori_mean_mrad": 0.0}
    assert report.chosen == "pass 3" and q[0, 0] == pytest.approx(0.5e-3)
    assert len({q_run.tobytes() for q_run in runs}) == len(runs)    # no command run twice
