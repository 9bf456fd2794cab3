"""J, B and friction per direction from motor currents (Erkorkmaz & Altintas 2001)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from precontour.identification.physical import identify_physical

from vm_logs import hidden_plant, make_log


@pytest.mark.parametrize("resolution", [None, np.array([1e-4] * 3 + [1e-6] * 2)])
def test_recovers_inertia_damping_and_friction(machine, resolution):
    """Virtual machine with friction (no friction feed-forward, so the current is the whole
    motor torque): J and B within 1 %, each side's Ts and Tc within 2 % (encoder exact) or
    J, B within 3 % and friction within 5 % (0.1 um / 1 urad encoder)."""
    plant = hidden_plant(machine)
    log, _ = make_log(machine, plant, ("X", "A"), friction=True, ff_friction=False,
                      currents=True, resolution=resolution)
    tol, ftol = (0.01, 0.02) if resolution is None else (0.03, 0.05)
    for axis, i in (("X", 0), ("A", 3)):
        found = identify_physical(machine.drive(axis), log.actual[axis], log.current[axis],
                                  log.period)
        true = plant.drives[i]
        assert found.J == pytest.approx(true.J, rel=tol)
        assert found.B == pytest.approx(true.B, rel=tol)
        for key in ("Ts_pos", "Tc_pos", "Ts_neg", "Tc_neg"):
            assert getattr(found.friction, key) == pytest.approx(getattr(true.friction, key),
                                                                 rel=ftol), key


def test_coulomb_only_without_base_friction(machine):
    """A base drive without friction: Coulomb per direction (Ts = Tc), still with J and B.
    The plant's friction is Tc (exp(-w/W1) + 1 - exp(-w/W2)), constant only where W1 = W2
    (the positive side); on the negative side W1 != W2 leaves a 3 % model error."""
    plant = dataclasses.replace(machine, drives=tuple(
        dataclasses.replace(d, friction=dataclasses.replace(
            d.friction, Ts_pos=d.friction.Tc_pos, Ts_neg=d.friction.Tc_neg)) for d in machine.drives))
    log, _ = make_log(machine, plant, ("X",), friction=True, ff_friction=False, currents=True)
    base = dataclasses.replace(machine.drive("X"), friction=None)
    found = identify_physical(base, log.actual["X"], log.current["X"], log.period)
    true = plant.drives[0]
    assert found.J == pytest.approx(true.J, rel=0.01)
    assert found.friction.Tc_pos == pytest.approx(true.friction.Tc_pos, rel=0.02)
    assert found.friction.Tc_neg == pytest.approx(true.friction.Tc_neg, rel=0.04)
    assert found.friction.Ts_pos == found.friction.Tc_pos


def test_too_little_motion_gives_none(machine):
    x = np.zeros(500)
    assert identify_physical(machine.drive("X"), x, np.zeros(500), 1e-3) is None
