"""Logs made by the virtual machine for the identification tests."""

from __future__ import annotations

import dataclasses

import numpy as np

from precontour.simulation import simulate
from precontour.identification import excitation_trajectory
from precontour.identification.servo_log import ServoLog
from precontour.machine.drives import AXES
from precontour.tables import write_columns

#: A plant whose J and B differ from zhang2013's (the "hidden" machine of the tests).
J_FACTORS = (1.25, 0.75, 1.3, 0.8, 1.2)
B_FACTORS = (0.75, 1.3, 0.7, 1.25, 1.3)


def hidden_plant(machine):
    return dataclasses.replace(machine, drives=tuple(
        dataclasses.replace(d, J=d.J * fj, B=d.B * fb)
        for d, fj, fb in zip(machine.drives, J_FACTORS, B_FACTORS)))


def make_log(machine, plant, axes, *, controller="pid-high", friction=False, ff_friction=None,
             resolution=None, noise=None, currents=False, travel=None, seed=0):
    """(ServoLog, SimulationResult) of the excitation of ``axes`` run on ``plant``."""
    exc = excitation_trajectory(machine, axes=axes, travel=travel)
    sim = simulate(exc.t, exc.q, plant, controller, mode="discrete", friction=friction,
                   ff_friction=friction if ff_friction is None else ff_friction,
                   encoder_resolution=resolution)
    actual = sim.q_act
    if resolution is not None:
        actual = np.round(actual / resolution) * resolution
    if noise is not None:
        actual = actual + np.random.default_rng(seed).normal(0.0, 1.0, actual.shape) * noise
    current = {a: plant.drives[i].ka * sim.u[:, i] for i, a in enumerate(AXES)} if currents else {}
    log = ServoLog(source="<virtual machine>", t=exc.t,
                   command={a: exc.q[:, i] for i, a in enumerate(AXES)},
                   actual={a: actual[:, i] for i, a in enumerate(AXES)}, current=current)
    return log, sim


def write_log_file(path, traj, plant, letters, *, controller="pid-low", currents=()):
    """The commands ``traj`` run on ``plant`` (discrete control, no friction) written as a
    servo-log table at ``path``: t, each axis by its letter in ``letters`` and its ``_act``,
    and the motor current ``I_`` of the axes in ``currents``; returns the file's path and the
    SimulationResult."""
    sim = simulate(traj.t, traj.q, plant, controller, mode="discrete", friction=False,
                   ff_friction=False)
    columns = {"t": traj.t}
    for i, axis in enumerate(letters):
        columns[axis] = traj.q[:, i]
        columns[f"{axis}_act"] = sim.q_act[:, i]
        if axis in currents:
            columns[f"I_{axis}"] = plant.drives[i].ka * sim.u[:, i]
    return write_columns(path, columns), sim


#: A shorter excitation for the tests that need no friction-free drift speed.
SHORT_TRAVEL = {"X": 5.0, "Y": 5.0, "Z": 5.0, "A": 0.1, "C": 0.1}
