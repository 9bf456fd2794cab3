"""From a log to a machine file: axes kept from the base, the file parses, options checked."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.errors import InputError
from precontour.identification import identify
from precontour.machine.machine_file import machine_data, parse_machine

from vm_logs import SHORT_TRAVEL, hidden_plant, make_log


@pytest.fixture(scope="module")
def x_only_result(machine):
    log, _ = make_log(machine, machine, ("X",), travel=SHORT_TRAVEL)
    data, _ = machine_data("zhang2013")
    return identify(log, machine, data, base_controller="pid-high")


def test_axes_that_never_move_keep_the_base_model(machine, x_only_result):
    result = x_only_result
    assert set(result.axes) == {"X"}
    for axis in ("Y", "Z", "A", "C"):
        note = result.notes[axis]
        assert "never moves" in note and "kept the base model (pid-high)" in note
        assert "\n" not in note
    ident = result.identified_models()
    base = machine.error_models("pid-high")
    w = np.geomspace(1, 3000, 30) * 1j
    for i in range(1, 5):
        h_ident = np.polyval(ident[i].num, w) / np.polyval(ident[i].den, w)
        h_base = np.polyval(base[i].num, w) / np.polyval(base[i].den, w)
        np.testing.assert_allclose(h_ident, h_base, rtol=1e-12, atol=1e-15)


def test_machine_file_round_trip(machine, x_only_result):
    again = parse_machine(x_only_result.text)
    assert again.controller("identified").type == "tf"
    assert again.drives == machine.drives
    assert set(again.controllers) == set(machine.controllers) | {"identified"}
    for a, b in zip(again.controller("identified").axes, x_only_result.machine.controller("identified").axes):
        assert a == b


def test_physical_parameters_go_into_the_drive_table(machine):
    plant = hidden_plant(machine)
    log, _ = make_log(machine, plant, ("Z",), friction=True, ff_friction=False, currents=True,
                      travel=SHORT_TRAVEL)
    data, _ = machine_data("zhang2013")
    result = identify(log, machine, data, order=3)
    z = result.machine.drive("Z")
    assert z.J == pytest.approx(plant.drive("Z").J, rel=0.02)
    assert z.B == pytest.approx(plant.drive("Z").B, rel=0.02)
    assert z.friction.Tc_neg == pytest.approx(plant.drive("Z").friction.Tc_neg, rel=0.05)
    assert result.machine.drive("X") == machine.drive("X")
    assert result.axes["Z"].order == 3
    # Every identified axis has its drive from the currents: the tf loop names the controller
    # the drives run (pid-high, the machine's first linear one), what compensate learns against.
    assert result.machine.controller("identified").base == "pid-high" == result.base_controller.name
    assert 'base = "pid-high"' in result.text and "base" not in result.notes


@pytest.mark.parametrize("order", ["0", "x", 11, "2.5"])
def test_bad_order(machine, x_only_result, order):
    data, _ = machine_data("zhang2013")
    with pytest.raises(InputError, match="field 'order'"):
        identify(x_only_result.log, machine, data, order=order)


def test_bad_name(machine, x_only_result):
    data, _ = machine_data("zhang2013")
    with pytest.raises(InputError, match="field 'name'"):
        identify(x_only_result.log, machine, data, name="has space")


def test_currents_that_do_not_fit_the_motion_name_the_log_and_the_column(machine):
    """Currents of the wrong sign give a negative inertia: an error naming the log and I_X,
    not the identified machine file's [drives.X] J."""
    import dataclasses
    import warnings

    log, _ = make_log(machine, machine, ("X",), travel=SHORT_TRAVEL, currents=True)
    flipped = dataclasses.replace(log, source="log.csv", current={"X": -log.current["X"]})
    data, _ = machine_data("zhang2013")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match=r"^log.csv, field 'I_X': the motor current of X "
                                             r"does not fit its motion: it gives an inertia "
                                             r"J = -[0-9.e-]+ kg m\^2 \(must be > 0\)"):
            identify(flipped, machine, data, base_controller="pid-high")
