"""Measure identification on a hidden plant (README, "Calibrating to your machine").

The hidden plant is zhang2013 with each drive's J and B changed by 20-30 % (factors below),
run by the virtual machine as the realistic machine (discrete controller at 1 kHz, Stribeck
friction with stick-slip, feed-forward friction compensation), optionally with encoder
quantisation. The excitation of ``precontour excite`` is run on it to make the log, with the
motor currents (the controller's output plus the friction feed-forward, the whole motor
torque over kt); ``identify`` gives the ``tf`` loops and, from the currents, J, B and friction
per drive. The identified machine is then evaluated on the built-in paths, which are not in
the log:

* prediction: max |e_predicted - e_measured| per axis in % of max|e_measured|, by the linear
  models (identified tf, nominal, the plant's own) and by simulating the identified physical
  model (identified J, B, friction, the base controller, the realistic machine);
* compensation on the hidden plant: reduction of the max and mean tool-tip and orientation
  contour errors by one linear pass with each linear model, and by the identified tf model's
  pass followed by learning (``--learn`` passes) against the realistic virtual machine of the
  identified drives with the base controller (what ``precontour compensate --machine IDENT.toml
  --controller identified --learn N`` does), against the nominal drives, against the
  hidden plant itself (the best learning can do), and against the identified tf loops
  themselves (no friction: what compensate does when the log had no currents); with
  ``--quantize`` also against the hidden plant with its quantised encoder.

Usage: python scripts/measure_identification.py [--controller pid-high] [--quantize] [--learn 4]
       [--friction-mismatch] [--paths circle,cone,fan,paper]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from precontour import (ReferencePath, builtin_path, compensate, contour_errors, generate_trajectory,
                        load_machine, simulate)
from precontour.compensation.stops import DEFAULT_LEARNING_PASSES
from precontour.identification import excitation_trajectory, identify
from precontour.identification.servo_log import ServoLog
from precontour.machine.drives import AXES
from precontour.machine.machine_file import machine_data
from precontour.simulation.virtual_machine import (FF_SPEED_DEADBAND, REALISTIC, StackedFriction,
                                                   realistic_actual)

J_FACTORS = (1.25, 0.75, 1.3, 0.8, 1.2)
B_FACTORS = (0.75, 1.3, 0.7, 1.25, 1.3)
PATHS = ("circle", "cone", "fan", "paper")


#: ``--friction-mismatch``: the plant's friction levels and Stribeck speeds differ from the
#: base machine's too; identify takes the Stribeck speeds W1, W2 from the base machine, so the
#: identified friction law then has the wrong shape.
FRICTION_MISMATCH = {"Ts": 1.2, "Tc": 0.85, "W1": 1.5, "W2": 1.5}


def hidden_plant(machine, friction_mismatch: bool = False):
    drives = tuple(dataclasses.replace(d, J=d.J * fj, B=d.B * fb)
                   for d, fj, fb in zip(machine.drives, J_FACTORS, B_FACTORS))
    if friction_mismatch:
        drives = tuple(dataclasses.replace(d, friction=dataclasses.replace(d.friction, **{
            f"{key}_{side}": getattr(d.friction, f"{key}_{side}") * factor
            for key, factor in FRICTION_MISMATCH.items() for side in ("pos", "neg")}))
            for d in drives)
    return dataclasses.replace(machine, drives=drives)


def motor_currents(sim, q, machine) -> np.ndarray:
    """Motor currents (N, 5) of a discrete run with friction feed-forward: (ka kt u + Tff)/kt,
    Tff the feed-forward torque at the commanded motor speed held over each period."""
    ts = sim.t[1] - sim.t[0]
    rg, ka, kt = (np.array([getattr(d, k) for d in machine.drives]) for k in ("rg", "ka", "kt"))
    w_cmd = np.vstack([np.diff(q, axis=0) / ts / rg, np.zeros((1, q.shape[1]))])
    tff = np.where(np.abs(w_cmd) < FF_SPEED_DEADBAND, 0.0, StackedFriction(machine.drives).many(w_cmd))
    return ka * sim.u + tff / kt


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--controller", default="pid-high")
    parser.add_argument("--quantize", action="store_true",
                        help="encoder resolution 0.1 um / 1 urad on the hidden plant")
    parser.add_argument("--learn", type=int, default=DEFAULT_LEARNING_PASSES,
                        help="learning passes against the virtual machines")
    parser.add_argument("--paths", default=",".join(PATHS),
                        help=f"built-in paths, comma-separated (default {','.join(PATHS)})")
    parser.add_argument("--friction-mismatch", action="store_true",
                        help="the plant's friction differs from the base machine's: static "
                             "levels x1.2, Coulomb x0.85, Stribeck speeds x1.5")
    args = parser.parse_args()
    base = load_machine("zhang2013")
    plant = hidden_plant(base, args.friction_mismatch)
    res = np.array([1e-4] * 3 + [1e-6] * 2) if args.quantize else None
    run = dict(REALISTIC, encoder_resolution=res)

    start = time.perf_counter()
    exc = excitation_trajectory(base)
    sim = simulate(exc.t, exc.q, plant, args.controller, **run)
    actual = np.round(sim.q_act / res) * res if res is not None else sim.q_act
    current = motor_currents(sim, exc.q, plant)
    log = ServoLog(source="<hidden plant>", t=exc.t,
                   command={a: exc.q[:, i] for i, a in enumerate(AXES)},
                   actual={a: actual[:, i] for i, a in enumerate(AXES)},
                   current={a: current[:, i] for i, a in enumerate(AXES)})
    t_sim = time.perf_counter() - start
    data, _ = machine_data("zhang2013")
    result = identify(log, base, data, base_controller=args.controller)
    t_id = time.perf_counter() - start - t_sim
    identified = result.machine
    drives_controller = identified.controller(result.name).base or args.controller
    print(f"controller {args.controller}, quantized {args.quantize}, friction mismatch "
          f"{args.friction_mismatch}: excitation {exc.duration:.1f} s "
          f"({exc.n_samples} samples), simulated in {t_sim:.1f} s, identified in {t_id:.1f} s; "
          f"tf base controller {drives_controller}")
    for axis, fit in result.axes.items():
        print(f"  {axis}: order {fit.order}, fit {fit.fit_pct:.2f} %, held-out {fit.holdout_pct:.2f} %")
    print("identified / hidden plant: J B Ts+ Tc+ Ts- Tc-")
    for axis, p in result.physical.items():
        true = plant.drive(axis)
        ratios = [p.J / true.J, p.B / true.B] + [getattr(p.friction, k) / getattr(true.friction, k)
                                                 for k in ("Ts_pos", "Tc_pos", "Ts_neg", "Tc_neg")]
        print(f"  {axis}: " + " ".join(f"{r:.4f}" for r in ratios)
              + f"  (torque fit {p.torque_fit_pct:.2f} %, {p.windows} windows)")
    # "plant": the hidden plant's own continuous linear model (what a perfect J, B would give).
    models = {"identified": result.identified_models(),
              "nominal": base.controller(args.controller).error_models(base.drives),
              "plant": base.controller(args.controller).error_models(plant.drives)}
    # Learning models: the realistic virtual machine with the drives of each machine.
    learning = {"identified": identified, "nominal": base, "plant": plant,
                "identified tf": identified}
    if res is not None:
        learning["plant with its encoder"] = plant
    print("\nprediction error, max|e_pred - e| in % of max|e| per axis X Y Z A C")
    comp_rows = []
    for name in args.paths.split(","):
        traj = generate_trajectory(builtin_path(name), base)
        truth = simulate(traj.t, traj.q, plant, args.controller, **run)
        e = truth.e
        peak = np.abs(e).max(axis=0)
        # An axis whose error stays below 0.1 um / 0.1 urad barely moves on this path: "-".
        moving = peak > np.array([1e-4] * 3 + [1e-7] * 2)
        predictions = {label: predict_tracking_of(traj, mods) for label, mods in models.items()}
        predictions["physical"] = simulate(traj.t, traj.q, identified, drives_controller,
                                           **REALISTIC).e
        line = [f"{name:7s}"]
        for label, ep in predictions.items():
            pct = 100 * np.abs(ep - e).max(axis=0) / np.where(moving, peak, np.nan)
            digits = 2 if label == "physical" else 1
            line.append(f"{label} " + " ".join("  -  " if not np.isfinite(p) else f"{p:5.{digits}f}"
                                                for p in pct))
        print(" | ".join(line), " (max|e| um/mrad " + " ".join(f"{1e3 * p:.1f}" for p in peak) + ")")
        reference = ReferencePath.from_trajectory(traj)
        before = contour_errors(reference, truth.q_act, base.kinematics).summary()
        cases = [(label, mods, None) for label, mods in models.items()]
        cases += [(f"identified + learning on {label}", models["identified"], machine)
                  for label, machine in learning.items()]
        for label, mods, learn_machine in cases:
            # "identified tf": the tf loops themselves (no drives, no friction).
            learn_controller = result.name if label.endswith(" tf") else drives_controller
            actual = None if learn_machine is None else realistic_actual(traj.t, learn_machine,
                                                                         learn_controller)
            if label.endswith("encoder"):
                def actual(q, t=traj.t):
                    return simulate(t, q, plant, args.controller, **run).q_act
            options = {} if actual is None else dict(machine_actual=actual,
                                                     learning_passes=args.learn)
            comp = compensate(traj, base.kinematics, mods, reference=reference, min_passes=1,
                              **options)
            after_sim = simulate(comp.trajectory.t, comp.trajectory.q, plant, args.controller, **run)
            after = contour_errors(reference, after_sim.q_act, base.kinematics).summary()
            red = {k: 100 * (1 - after[k] / before[k]) for k in
                   ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")}
            kept = "" if comp.learning is None else f", kept {comp.learning.chosen}"
            comp_rows.append((name, label, before, after, red, kept))
    print(f"\ncontour-error reduction on the hidden plant, %: tip max / mean, orientation max / "
          f"mean (one linear pass; learning: {args.learn} passes)")
    for name, label, before, after, red, kept in comp_rows:
        print(f"{name:7s} {label:36s} {red['tip_max_um']:6.1f} / {red['tip_mean_um']:5.1f}, "
              f"{red['ori_max_mrad']:6.1f} / {red['ori_mean_mrad']:5.1f}   (tip max {before['tip_max_um']:.2f} -> "
              f"{after['tip_max_um']:.2f} um, mean {before['tip_mean_um']:.2f} -> "
              f"{after['tip_mean_um']:.3f} um{kept})")


def predict_tracking_of(traj, models) -> np.ndarray:
    from precontour import predict_tracking
    return predict_tracking(traj.t, traj.q, models)(traj.t)


if __name__ == "__main__":
    main()
