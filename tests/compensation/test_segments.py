"""Learning segment by segment (compensation/segments.py): the same guarantees as learning the
whole program, close to its result, in bounded memory; long programs are no longer refused."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import servo_of
from precontour.compensation.pieces import AT_ONCE_SAMPLES
from precontour.compensation.segments import learn_by_segments, plan_segments
from precontour.compensation.within_limits import compensate_within_limits, learn_within_limits
from precontour.compensation.blocks import block_starts, judge
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.ensemble import MachineEnsemble, ensemble_actual
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.trajectory.sampled import Trajectory

from test_within_limits import _nowhere_worse_on_every_draw

#: Kept samples per segment forced on the test path (7.6 s at 1 ms after slowing down):
#: three segments, the second and third with lead-ins that start mid-motion.
SEGMENT = 2500


def test_segmented_learning_is_nowhere_worse_and_close_to_learning_the_whole(machine):
    """`paper` at 35 mm/min (7.6 s) with `pid-high`, learned (4 passes, the default ensemble)
    whole and in forced segments of 2500 samples (lead-ins of 2.0 s from mid-motion). Checked
    independently, each draw simulated on its own over the whole program: the segmented
    command is nowhere worse than uncompensated on every draw, in whole and in every 0.1 s
    window. Measured: whole 1.428 um / 0.0659 um (worst-draw tip max / mean, 17.1 / 1.29
    uncompensated, 1.76 / 0.091 the linear pass), segmented 1.432 / 0.0672 (the segments read
    the whole program's encoder noise at their samples; 1.427 / 0.0690 while each drew its
    own), score 0.995 of the whole's; hence bounds of 1.05 on the score and 1.10 on the
    mean."""
    controller = "pid-high"
    models = machine.error_models(controller)
    traj = generate_trajectory(builtin_path("paper"), machine, feed=35.0)
    limited = compensate_within_limits(servo_of(machine, controller), traj)
    reference = limited.reference
    segments = plan_segments(reference, models, SEGMENT)
    assert len(segments) == 3 and all(s.start > 0 for s in segments[1:])
    assert all(s.start < s.keep_start for s in segments[1:])      # lead-ins mid-program
    sizes = []

    def machine_of(t, start):
        sizes.append(t.size)
        return ensemble_actual(t, machine, controller, start=start)

    segmented = learn_by_segments(servo_of(machine, controller), limited, machine_of, 4,
                                  segment_samples=SEGMENT)
    # bounded memory: no machine run covers the whole program, only a segment and its overlaps
    assert len(sizes) == 3 and max(sizes) < reference.n_samples
    assert sizes == [s.stop - s.start for s in segments]
    whole = learn_within_limits(servo_of(machine, controller), limited,
                                ensemble_actual(reference.t, machine, controller), 4)
    q = segmented.result.trajectory.q
    assert segmented.check.ok
    assert segmented.result.learning.chosen.startswith("by segment (3)")
    ensemble = MachineEnsemble()
    assert _nowhere_worse_on_every_draw(reference, q, machine, controller, ensemble) <= 0.0
    path = ReferencePath.from_trajectory(reference)
    starts = block_starts(reference.n_samples, reference.ts)
    actual = ensemble_actual(reference.t, machine, controller, ensemble)

    def judged(command):
        return judge([contour_errors(path, a, machine.kinematics) for a in actual(command)],
                     starts)

    on_segments, on_whole = judged(q), judged(whole.result.trajectory.q)
    assert on_segments.score <= 1.05 * on_whole.score, (on_segments.worst, on_whole.worst)
    assert on_segments.worst["tip_mean_um"] <= 1.10 * on_whole.worst["tip_mean_um"]


def test_short_programs_learn_whole(machine, monkeypatch):
    """At most AT_ONCE_SAMPLES samples, ``run``'s learning is the whole-program learning
    itself (the commands of before): learn_by_segments is not called."""
    from precontour.compensation import routes   # where run's learning looks them up

    called = []
    monkeypatch.setattr(routes, "learn_by_segments",
                        lambda *a, **k: called.append(1) or pytest.fail("segmented"))
    monkeypatch.setattr(routes, "learn_within_limits", lambda servo, limited, *a, **k: limited)
    traj = generate_trajectory(builtin_path("paper"), machine)
    servo = servo_of(machine, "pid-high")
    limited = compensate_within_limits(servo, traj)
    assert routes.learn_on_ensemble(servo, limited, 4) is limited
    assert not called


def test_can_learn_takes_long_programs_within_the_limits(machine, caplog):
    """``can_learn`` no longer refuses a trajectory above AT_ONCE_SAMPLES (learned segment by
    segment); learning that runs it whole (``whole=True``, the unconstrained compensation)
    still does, with its notice. A trajectory off the servo period is refused either way."""
    from precontour.compensation.routes import can_learn
    from precontour.machine.servo import load_servo

    servo = load_servo(machine, "pid-high")
    n = AT_ONCE_SAMPLES + 1
    t = np.arange(n) * machine.servo_period
    long = Trajectory(t=t, q=np.zeros((n, 5)))
    assert can_learn(servo, long)
    assert caplog.text == ""
    assert not can_learn(servo, long, whole=True)
    assert "compensated in pieces" in caplog.text
    caplog.clear()
    off = Trajectory(t=np.arange(10) * 2 * machine.servo_period, q=np.zeros((10, 5)))
    assert not can_learn(servo, off)
    assert "servo period" in caplog.text
