"""The ensemble of virtual machines: its options object, its draws, and the model that runs
them side by side."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.machine.machine_file import load_machine
from precontour.simulation.ensemble import MachineEnsemble, ensemble_actual
from precontour.simulation.virtual_machine import REALISTIC, simulate

MACHINE = load_machine("zhang2013")


def test_the_options_are_checked():
    for bad, message in ((dict(draws=0), "draws must be an integer >= 1"),
                         (dict(draws=2.5), "draws must be an integer >= 1"),
                         (dict(friction_spread=1.0), r"friction_spread must be within \[0, 1\)"),
                         (dict(inertia_spread=-0.1), r"inertia_spread must be within \[0, 1\)"),
                         (dict(damping_spread=float("nan")), "damping_spread must be within"),
                         (dict(encoder_resolution=(1e-5,)), "encoder_resolution must be two"),
                         (dict(encoder_noise=(1e-6, -1.0)), "encoder_noise must be two"),
                         (dict(seed=-1), "seed must be an integer >= 0")):
        with pytest.raises(ValueError, match=message):
            MachineEnsemble(**bad)
    with pytest.raises(ValueError, match="for both kinds of axis or for neither"):
        MachineEnsemble(encoder_resolution=(1e-5, 0.0)).options(10)


def test_draws_are_deterministic_within_their_spreads_and_draw_0_is_the_machine():
    ensemble = MachineEnsemble(draws=6, seed=7)
    options = ensemble.options(50)
    assert len(options) == 6 and options[0] == {}
    again = MachineEnsemble(draws=6, seed=7).options(50)
    fewer = MachineEnsemble(draws=3, seed=7).options(50)
    other = MachineEnsemble(draws=6, seed=8).options(50)
    for d in range(1, 6):
        for key, value in options[d].items():
            np.testing.assert_array_equal(value, again[d][key])
            if d < 3:           # a draw does not depend on how many are drawn
                np.testing.assert_array_equal(value, fewer[d][key])
        assert not np.array_equal(options[d]["friction_scale"], other[d]["friction_scale"])
        assert options[d]["friction_scale"].shape == (2, 5)
        assert np.all(np.abs(options[d]["friction_scale"] - 1) <= 0.02)
        assert np.all(np.abs(options[d]["inertia_scale"] - 1) <= 0.01)
        assert np.all(np.abs(options[d]["damping_scale"] - 1) <= 0.01)
        res = options[d]["encoder_resolution"]
        np.testing.assert_array_equal(res, [1e-5] * 3 + [1e-7] * 2)
        assert np.all((options[d]["encoder_offset"] >= 0) & (options[d]["encoder_offset"] < res))
        noise = options[d]["encoder_noise"]
        assert noise.shape == (50, 5)
        assert np.all(np.abs(noise[:, :3]).max(axis=0) < 6 * 2e-6)
    assert MachineEnsemble(nominal=False).options(5)[0] != {}
    plain = MachineEnsemble(encoder_resolution=(0, 0), encoder_noise=(0, 0)).options(5)[1]
    assert "encoder_resolution" not in plain and "encoder_noise" not in plain
    assert "friction +-2 %" in ensemble.describe() and "seed 7" in ensemble.describe()


def test_the_ensemble_model_runs_every_draw():
    t = np.arange(300) * MACHINE.servo_period
    s = np.clip(t / 0.25, 0, 1)
    q = np.outer(s * s * (3 - 2 * s), [5.0, -3.0, 1.0, 0.2, -0.3])
    ensemble = MachineEnsemble(draws=3, seed=2)
    actual = ensemble_actual(t, MACHINE, "pid-high", ensemble)
    motions = actual(q)
    assert motions.shape == (3, 300, 5)
    np.testing.assert_array_equal(motions[0],
                                  simulate(t, q, MACHINE, "pid-high", **REALISTIC).q_act)
    draw_2 = ensemble.options(300)[2]
    np.testing.assert_array_equal(motions[2], simulate(t, q, MACHINE, "pid-high", **REALISTIC,
                                                       **draw_2).q_act)
    assert not np.array_equal(motions[1], motions[2])


def test_a_stretch_reads_the_noise_of_its_samples_in_the_whole_program(monkeypatch):
    """A draw's encoder noise at sample k is the same whether the draw is made for the whole
    program or for a stretch starting at ``start`` (learning by segment decides on the
    machines the whole program is checked on), across the noise blocks' boundaries; a program
    within one block reads what it read before the blocks."""
    from precontour.simulation import ensemble as module

    monkeypatch.setattr(module, "NOISE_BLOCK", 64)
    ensemble = MachineEnsemble(draws=3, seed=4)
    whole = ensemble.option(2, 300)
    for start, n in ((0, 10), (5, 59), (60, 10), (64, 64), (100, 200), (299, 1)):
        part = ensemble.option(2, n, start=start)
        np.testing.assert_array_equal(part["encoder_noise"],
                                      whole["encoder_noise"][start:start + n])
        for key in ("friction_scale", "inertia_scale", "damping_scale", "encoder_offset"):
            np.testing.assert_array_equal(part[key], whole[key])
    # independent blocks: block 1 is not block 0 again
    assert not np.allclose(whole["encoder_noise"][:64], whole["encoder_noise"][64:128])
    monkeypatch.setattr(module, "NOISE_BLOCK", 1 << 19)
    rng = np.random.default_rng([4, 2])
    rng.uniform(-1, 1, (2, 5)), rng.uniform(-1, 1, 5), rng.uniform(-1, 1, 5)
    rng.uniform(0, 1, 5)
    np.testing.assert_array_equal(ensemble.option(2, 300)["encoder_noise"],
                                  rng.standard_normal((300, 5)) * np.array([2e-6] * 3
                                                                           + [2e-8] * 2))
    with pytest.raises(ValueError, match="start must be an integer >= 0"):
        ensemble.option(1, 10, start=-1)


def test_a_rerun_is_the_same_machines_with_encoder_noise_drawn_afresh():
    """``rerun()``: the friction, inertia, damping and encoder grid of every draw as they
    were, the encoder noise new (and a function of the sample, as the draws' own: a stretch
    reads the whole program's), draw 0 the machine file's machine still; the ensemble model
    runs it as ``.repeat`` where the draws have noise, and has none where they do not."""
    ensemble = MachineEnsemble(draws=3, seed=4)
    again = ensemble.rerun()
    assert again.repeat == 1 and again.draws == 3 and "run 1" in again.describe()
    for draw in (1, 2):
        first, second = ensemble.option(draw, 700), again.option(draw, 700)
        for key in ("friction_scale", "inertia_scale", "damping_scale", "encoder_offset",
                    "encoder_resolution"):
            np.testing.assert_array_equal(first[key], second[key])
        assert not np.allclose(first["encoder_noise"], second["encoder_noise"])
        stretch = again.option(draw, 200, start=500)["encoder_noise"]
        np.testing.assert_array_equal(stretch, second["encoder_noise"][500:])
    assert again.option(0, 700) == {} and ensemble.rerun(2).option(1, 700)["encoder_noise"] \
        .tolist() != second["encoder_noise"].tolist()
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="repeat must be an integer >= 1"):
            ensemble.rerun(bad)
    with pytest.raises(ValueError, match="repeat must be an integer >= 0"):
        MachineEnsemble(repeat=-1)

    machine = load_machine("zhang2013")
    t = np.arange(300) * machine.servo_period
    q = np.zeros((300, 5))
    q[:, 0] = 1e-3 * np.sin(2 * np.pi * t)
    model = ensemble_actual(t, machine, "pid-high", ensemble)
    rotary = [d.is_rotary for d in machine.drives]
    expected = [simulate(t, q, machine, "pid-high", **REALISTIC, **option).q_act
                for option in again.options(300, rotary)]
    np.testing.assert_array_equal(model.repeat(q), np.stack(expected))
    assert ensemble_actual(t, machine, "pid-high",
                           MachineEnsemble(draws=3, encoder_noise=(0, 0))).repeat is None
    assert ensemble_actual(t, machine, "pid-high", MachineEnsemble(draws=1)).repeat is None
    assert ensemble_actual(t, machine, "pid-high",
                           MachineEnsemble(draws=1, nominal=False)).repeat is not None
    assert ensemble_actual(t, machine, "pid-high", again).repeat is None
