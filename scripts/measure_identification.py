"""Measure identification on a hidden plant (README, "Calibrating to your machine").

The hidden plant is zhang2013 with each drive's J and B changed by 20-30 % (factors below),
run by the virtual machine as the realistic machine (discrete controller at 1 kHz, Stribeck
friction with stick-slip, feed-forward friction compensation), optionally with encoder
quantisation. The excitation of ``precontour excite`` is run on it to make the log; the
identified model is then evaluated on the built-in paths, which are not in the log:

* prediction: max |e_predicted - e_measured| per axis in % of max|e_measured|, identified vs
  nominal (base) model;
* compensation: one contour pre-compensation pass with each model, run on the hidden plant;
  reduction of the max and mean tool-tip and orientation contour errors.

Usage: python scripts/measure_identification.py [--controller pid-high] [--quantize]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from precontour import (ReferencePath, builtin_path, compensate, contour_errors, generate_trajectory,
                        load_machine, predict_tracking, simulate)
from precontour.identification import excitation_trajectory, identify
from precontour.identification.servo_log import ServoLog
from precontour.machine.drives import AXES
from precontour.machine.machine_file import machine_data

J_FACTORS = (1.25, 0.75, 1.3, 0.8, 1.2)
B_FACTORS = (0.75, 1.3, 0.7, 1.25, 1.3)
PATHS = ("circle", "cone", "fan", "paper")


def hidden_plant(machine):
    drives = tuple(dataclasses.replace(d, J=d.J * fj, B=d.B * fb)
                   for d, fj, fb in zip(machine.drives, J_FACTORS, B_FACTORS))
    return dataclasses.replace(machine, drives=drives)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--controller", default="pid-high")
    parser.add_argument("--quantize", action="store_true",
                        help="encoder resolution 0.1 um / 1 urad on the hidden plant")
    args = parser.parse_args()
    base = load_machine("zhang2013")
    plant = hidden_plant(base)
    res = np.array([1e-4] * 3 + [1e-6] * 2) if args.quantize else None
    run = dict(mode="discrete", friction=True, ff_friction=True, encoder_resolution=res)

    start = time.perf_counter()
    exc = excitation_trajectory(base)
    sim = simulate(exc.t, exc.q, plant, args.controller, **run)
    actual = np.round(sim.q_act / res) * res if res is not None else sim.q_act
    log = ServoLog(source="<hidden plant>", t=exc.t,
                   command={a: exc.q[:, i] for i, a in enumerate(AXES)},
                   actual={a: actual[:, i] for i, a in enumerate(AXES)}, current={})
    t_sim = time.perf_counter() - start
    data, _ = machine_data("zhang2013")
    result = identify(log, base, data, base_controller=args.controller)
    t_id = time.perf_counter() - start - t_sim
    print(f"controller {args.controller}, quantized {args.quantize}: excitation {exc.duration:.1f} s "
          f"({exc.n_samples} samples), simulated in {t_sim:.1f} s, identified in {t_id:.1f} s")
    for axis, fit in result.axes.items():
        print(f"  {axis}: order {fit.order}, fit {fit.fit_pct:.2f} %, held-out {fit.holdout_pct:.2f} %")
    # "plant": the hidden plant's own continuous linear model (what a perfect J, B would give).
    models = {"identified": result.identified_models(),
              "nominal": base.controller(args.controller).error_models(base.drives),
              "plant": base.controller(args.controller).error_models(plant.drives)}
    print("\nprediction error, max|e_pred - e| in % of max|e| per axis X Y Z A C")
    comp_rows = []
    for name in PATHS:
        traj = generate_trajectory(builtin_path(name), base)
        truth = simulate(traj.t, traj.q, plant, args.controller, **run)
        e = truth.e
        peak = np.abs(e).max(axis=0)
        line = [f"{name:7s}"]
        for label, mods in models.items():
            ep = predict_tracking(traj.t, traj.q, mods)(traj.t)
            # An axis whose error stays below 0.1 um / 0.1 urad barely moves on this path: "-".
            moving = peak > np.array([1e-4] * 3 + [1e-7] * 2)
            pct = 100 * np.abs(ep - e).max(axis=0) / np.where(moving, peak, np.nan)
            line.append(f"{label} " + " ".join("  -  " if not np.isfinite(p) else f"{p:5.1f}"
                                                for p in pct))
        print(" | ".join(line), " (max|e| um/mrad " + " ".join(f"{1e3 * p:.1f}" for p in peak) + ")")
        reference = ReferencePath.from_trajectory(traj)
        before = contour_errors(reference, truth.q_act, base.kinematics).summary()
        for label, mods in models.items():
            comp = compensate(traj, base.kinematics, mods, reference=reference, min_passes=1)
            after_sim = simulate(comp.trajectory.t, comp.trajectory.q, plant, args.controller, **run)
            after = contour_errors(reference, after_sim.q_act, base.kinematics).summary()
            red = {k: 100 * (1 - after[k] / before[k]) for k in
                   ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")}
            comp_rows.append((name, label, before, after, red))
    print("\ncontour-error reduction by one compensation pass on the hidden plant, %: "
          "tip max / mean, orientation max / mean")
    for name, label, before, after, red in comp_rows:
        print(f"{name:7s} {label:10s} {red['tip_max_um']:6.1f} / {red['tip_mean_um']:5.1f}, "
              f"{red['ori_max_mrad']:6.1f} / {red['ori_mean_mrad']:5.1f}   (tip max {before['tip_max_um']:.2f} -> "
              f"{after['tip_max_um']:.2f} um, mean {before['tip_mean_um']:.2f} -> {after['tip_mean_um']:.2f} um)")


if __name__ == "__main__":
    main()
