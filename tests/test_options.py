"""The options objects (precontour.options): each checks itself when made, with the command
line's one-line error named by its option, and the jobs take them in place of loose keywords,
to the same numbers as the former spellings."""

from __future__ import annotations

import numpy as np
import pytest

from precontour import (ContourTolerance, LearningOptions, LimitOptions, ToleranceOptions,
                        builtin_path, compensate, generate_trajectory, load_servo)
from precontour.errors import InputError
from precontour.simulation.ensemble import MachineEnsemble


@pytest.mark.parametrize("make, field, message", [
    (lambda: LearningOptions(passes=-1), "--learn", "must be a whole number >= 0, got -1"),
    (lambda: LearningOptions(passes=1.5), "--learn", "got 1.5"),
    (lambda: LearningOptions(passes=True), "--learn", "got True"),
    (lambda: LearningOptions(controller=""), "--learn-controller", "a controller's name"),
    (lambda: LearningOptions(ensemble=5), "ensemble", "must be a MachineEnsemble"),
    (lambda: LimitOptions(min_speed=0.0), "--min-speed", "a fraction in (0, 1], got 0.0"),
    (lambda: LimitOptions(min_speed=1.5), "--min-speed", "got 1.5"),
    (lambda: LimitOptions(min_speed=float("nan")), "--min-speed", "got nan"),
    (lambda: LimitOptions(keep="yes"), "--ignore-limits", "True or False"),
    (lambda: ToleranceOptions(None, feed_scale_max=2.0), "--feed-scale-max",
     "apply with --tolerance only"),
    (lambda: ToleranceOptions(ContourTolerance(0.01), feed_scale_max=0.5, feed_scale_min=0.6),
     "--feed-scale-min", "the lowest feed scale 0.6 is above the highest 0.5"),
    (lambda: ToleranceOptions(ContourTolerance(0.01), feed_scale_max=-1.0), "--feed-scale-max",
     "must be positive and finite, got -1.0"),
    (lambda: ToleranceOptions(0.01), "--tolerance", "must be a ContourTolerance"),
])
def test_options_check_themselves_in_one_line(make, field, message):
    with pytest.raises(InputError) as info:
        make()
    assert info.value.field == field
    assert message in str(info.value) and "\n" not in str(info.value)


def test_the_defaults_are_the_command_lines():
    assert LearningOptions().passes == 4 and LearningOptions().draws() == MachineEnsemble()
    assert LimitOptions() == LimitOptions(keep=True, min_speed=0.5)
    assert not ToleranceOptions().search
    assert (ToleranceOptions().feed_scale_max, ToleranceOptions().feed_scale_min) == (None, 0.05)
    # the highest feed by the program's format: the programmed feed for an NC program, twice
    # CL data's (issue 42 item 6); given, it is kept; without a search, 1 whatever the format
    searching = ToleranceOptions(ContourTolerance(0.01))
    assert searching.for_format("gcode").feed_scale_max == 1.0
    assert searching.for_format("clcsv").feed_scale_max == 2.0
    assert searching.for_format("apt").feed_scale_max == 2.0
    assert ToleranceOptions(ContourTolerance(0.01), 1.5).for_format("clcsv").feed_scale_max == 1.5
    assert ToleranceOptions().for_format("clcsv").feed_scale_max == 1.0
    tolerance = ContourTolerance.in_um(10, 0.05)
    assert (tolerance.tip, tolerance.orientation) == (1e-3 * 10, 1e-3 * 0.05)
    assert ContourTolerance.in_um(10).orientation is None


@pytest.fixture(scope="module")
def servo():
    return load_servo("zhang2013", "pid-high")


def test_compensate_takes_the_options_to_the_former_spellings_numbers(servo):
    """circle on pid-high slows down for its limits: the floor decides, at the default 0.5
    it is slowed by 0.035 s (measured), at 0.99 not at all and the compensation is left out
    in one window instead; the former keyword and LimitOptions give the same commands."""
    circle = generate_trajectory(builtin_path("circle"), servo.machine)
    with pytest.warns(DeprecationWarning, match=r"min_speed=: former spelling, removed in "
                      r"precontour 0\.2\.0; give limits=LimitOptions\(min_speed=\.\.\.\)"):
        former = compensate(servo, circle, min_speed=0.99)
    options = compensate(servo, circle, limits=LimitOptions(min_speed=0.99))
    np.testing.assert_array_equal(former.commands.q, options.commands.q)
    assert former.left_out == options.left_out and former.left_out
    default = compensate(servo, circle)
    assert options.commands.n_samples == circle.n_samples < default.commands.n_samples
    assert not default.left_out


def test_a_former_spelling_beside_an_options_object_is_refused(servo):
    circle = generate_trajectory(builtin_path("circle"), servo.machine)
    with pytest.raises(InputError, match="give ensemble in learn"):
        compensate(servo, circle, learn=LearningOptions(1), ensemble=MachineEnsemble())
    with pytest.raises(InputError, match="give min_speed in limits"):
        compensate(servo, circle, limits=LimitOptions(), min_speed=0.5)
    with pytest.raises(InputError, match="--learn"):
        compensate(servo, circle, learn=-1)


@pytest.mark.filterwarnings("ignore:.*former spelling:DeprecationWarning")
@pytest.mark.parametrize("options, message", [
    (dict(contour_tolerance=ToleranceOptions(ContourTolerance(0.01)), feed_scale_min=0.2),
     "give feed_scale_min in contour_tolerance"),
    (dict(feed_scale_max=2.0), "apply with --tolerance only"),
    (dict(contour_tolerance=ContourTolerance(0.01), feed_scale_max=0.5, feed_scale_min=0.6),
     "is above the highest"),
    (dict(limits=LimitOptions(keep=False)), "run keeps the machine's limits"),
    (dict(limits=LimitOptions(), min_speed=0.5), "give min_speed in limits"),
])
def test_run_program_checks_its_options_before_reading_anything(options, message, tmp_path):
    from precontour.workflow import run_program

    with pytest.raises(InputError, match=message):
        run_program(tmp_path / "not-read.ngc", machine="zhang2013", controller="pid-low",
                    **options)


def test_run_programs_former_spellings_warn_naming_the_release_and_the_options(tmp_path):
    """The former keyword spellings still work (the options are built from them before the
    program is read) and warn, pointed at the caller's line, with what replaces them."""
    from precontour.workflow import run_program

    with pytest.warns(DeprecationWarning) as caught:
        with pytest.raises(InputError):
            run_program(tmp_path / "not-there.ngc", machine="zhang2013", controller="pid-low",
                        contour_tolerance=ContourTolerance(0.01), feed_scale_min=0.2,
                        write_anyway=True)
    messages = [str(w.message) for w in caught if w.category is DeprecationWarning]
    assert messages == ["feed_scale_min=, write_anyway=: former spelling, removed in precontour "
                        "0.2.0; give contour_tolerance=ToleranceOptions(feed_scale_min=..., "
                        "write_anyway=...)"]
    assert all(w.filename == __file__ for w in caught)


def test_the_options_objects_do_not_warn(servo):
    import warnings

    circle = generate_trajectory(builtin_path("circle"), servo.machine)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        compensate(servo, circle, limits=LimitOptions(min_speed=0.99), learn=0)
