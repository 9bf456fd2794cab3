"""Measure identification on a hidden plant (docs/identification-measured.md).

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

Prints the results as Markdown; ``--output docs/identification-measured.md`` writes them as
that page's section for the chosen options (one section per combination of options, each
stamped with the date, the versions and the computer; the other sections stay).

Usage: python scripts/measure_identification.py [--controller pid-high] [--quantize] [--learn 4]
       [--friction-mismatch] [--paths circle,cone,fan,paper] [--output PAGE]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from docpage import markdown_table, replace_section, stamp

from precontour import builtin_path, generate_trajectory, load_machine, load_servo
from precontour.compensation.precompensate import compensate
from precontour.prediction import ReferencePath, contour_errors
from precontour.simulation import simulate
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


#: Column headers of the compensation tables, by case.
HEADERS = {"identified": "identified, 1 pass", "nominal": "nominal, 1 pass",
           "plant": "plant's model, 1 pass",
           "identified + learning on identified": "**identified + learning**",
           "identified + learning on nominal": "learning on nominal drives",
           "identified + learning on plant": "learning on the hidden plant",
           "identified + learning on identified tf": "learning on the `tf` loops",
           "identified + learning on plant with its encoder":
               "learning on the hidden plant with its encoder"}

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


INTRO = """# Identification, measured

How well [identification](identification.md) works, on a hidden plant: zhang2013 with each
drive's J and B changed by 20-30 % (J x1.25 / 0.75 / 1.3 / 0.8 / 1.2 and B x0.75 / 1.3 / 0.7 /
1.25 / 1.3 on X / Y / Z / A / C), run as the realistic virtual machine (discrete controller at
1 kHz, Stribeck friction with stick-slip, friction feed-forward). The log is the 107 s
excitation of `precontour excite` with the motor currents (the controller's output plus the
feed-forward torque, over kt); the identified machine is then evaluated on the built-in paths,
none of which is in the log. "plant" is the hidden plant's own continuous linear model (perfect
J and B): the best a linear model of the loop can do; "nominal" is the base machine's.

Written by `scripts/measure_identification.py --output docs/identification-measured.md`, one
section per combination of its options (controller, learning passes, `--quantize`: a 0.1 um /
1 urad encoder on the plant, `--friction-mismatch`: the plant's static friction x1.2, Coulomb
x0.85 and Stribeck speeds x1.5, so that the identified friction law has the wrong shape), each
stamped; do not edit by hand. Targets: each axis's tracking error predicted within about 10 %
of max\\|e\\|; at least 90 % of the mean and 80 % of the max tool-tip contour error removed on
the hidden plant."""


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
    parser.add_argument("--output", type=Path, default=None, metavar="PAGE",
                        help="write the results as this page's section for these options "
                             "(e.g. docs/identification-measured.md); default: print them")
    args = parser.parse_args()
    out = []
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
    out.append(f"Excitation {exc.duration:.1f} s ({exc.n_samples:,} samples), simulated on the "
               f"hidden plant in {t_sim:.1f} s, identified in {t_id:.1f} s; the `tf` "
               f"controller's base: {drives_controller}.\n")
    out.append("Fit of the `tf` loops on the log, % of max\\|e\\|:\n")
    out.append(markdown_table(["axis", "order", "fit %", "held-out %"],
                              [[axis, fit.order, f"{fit.fit_pct:.2f}", f"{fit.holdout_pct:.2f}"]
                               for axis, fit in result.axes.items()], "lrrr"))
    if result.physical:
        out.append("\nIdentified / hidden plant, from the motor currents (1 = exact):\n")
        rows = []
        for axis, p in result.physical.items():
            true = plant.drive(axis)
            ratios = [p.J / true.J, p.B / true.B] + [
                getattr(p.friction, k) / getattr(true.friction, k)
                for k in ("Ts_pos", "Tc_pos", "Ts_neg", "Tc_neg")]
            rows.append([axis] + [f"{r:.4f}" for r in ratios]
                        + [f"{p.torque_fit_pct:.2f}", p.windows])
        out.append(markdown_table(["axis", "J", "B", "Ts+", "Tc+", "Ts-", "Tc-",
                                   "torque fit %", "windows"], rows, "lrrrrrrrr"))
    # "plant": the hidden plant's own continuous linear model (what a perfect J, B would give).
    models = {"identified": result.identified_models(),
              "nominal": base.error_models(args.controller),
              "plant": base.controller(args.controller).error_models(plant.drives)}
    # Learning models: the realistic virtual machine with the drives of each machine.
    learning = {"identified": identified, "nominal": base, "plant": plant,
                "identified tf": identified}
    if res is not None:
        learning["plant with its encoder"] = plant
    prediction_rows, comp_rows = [], []
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
        row = [name]
        for label in ("identified", "physical", "nominal", "plant"):
            pct = 100 * np.abs(predictions[label] - e).max(axis=0) / np.where(moving, peak, np.nan)
            digits = 2 if label == "physical" else 1
            row.append(" / ".join("-" if not np.isfinite(p) else f"{p:.{digits}f}" for p in pct))
        row.append(" / ".join(f"{1e3 * p:.1f}" for p in peak))
        prediction_rows.append(row)
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
            # the base machine's servo with the models of this case
            servo = dataclasses.replace(load_servo(base, args.controller), models=tuple(mods))
            comp = compensate(servo, traj, reference=reference, min_passes=1, **options)
            after_sim = simulate(comp.trajectory.t, comp.trajectory.q, plant, args.controller, **run)
            after = contour_errors(reference, after_sim.q_act, base.kinematics).summary()
            red = {k: 100 * (1 - after[k] / before[k]) for k in
                   ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")}
            kept = "" if comp.learning is None else f", kept {comp.learning.chosen}"
            comp_rows.append((name, label, before, after, red, kept))
    out.append("\n**Prediction**: max\\|e_predicted - e\\| in % of max\\|e\\| per axis "
               "X / Y / Z / A / C (\"-\": the axis barely moves); \"identified physical\" "
               "simulates the identified J, B and friction with the base controller:\n")
    out.append(markdown_table(["path", "identified `tf`", "identified physical (simulated)",
                               "nominal (J, B off)", "plant's linear model",
                               "max\\|e\\| um / mrad"], prediction_rows))
    labels = list(dict.fromkeys(label for _, label, *_ in comp_rows))
    paths = list(dict.fromkeys(name for name, *_ in comp_rows))
    cell = {(name, label): (red, before, after, kept)
            for name, label, before, after, red, kept in comp_rows}
    for title, keys in (("tool-tip", ("tip_max_um", "tip_mean_um")),
                        ("orientation", ("ori_max_mrad", "ori_mean_mrad"))):
        out.append(f"\n**Compensation** on the hidden plant: reduction of the {title} contour "
                   f"error, max / mean, % (one linear pass with each model; learning: "
                   f"{args.learn} passes after the identified model's pass):\n")
        rows = [[name] + [f"{cell[name, label][0][keys[0]]:.1f} / "
                          f"{cell[name, label][0][keys[1]]:.1f}" for label in labels]
                for name in paths]
        out.append(markdown_table(["path"] + [HEADERS.get(label, label) for label in labels],
                                  rows))
    out.append("\nLearning kept, and the tip errors before and after (um), with the identified "
               "model and learning on the identified drives:\n")
    label = "identified + learning on identified"
    out.append(markdown_table(
        ["path", "kept", "tip max before / after", "tip mean before / after"],
        [[name, cell[name, label][3].removeprefix(", kept ") or "-",
          f"{cell[name, label][1]['tip_max_um']:.2f} / {cell[name, label][2]['tip_max_um']:.2f}",
          f"{cell[name, label][1]['tip_mean_um']:.2f} / {cell[name, label][2]['tip_mean_um']:.3f}"]
         for name in paths]))
    # the targets: prediction within 10 % on every moving axis; compensation with the
    # identified model and learning removing >= 90 % of the mean and >= 80 % of the max tip error
    met_prediction = {label: sum(all(v == "-" or float(v) <= 10 for v in row[1 + i].split(" / "))
                                 for row in prediction_rows)
                      for i, label in enumerate(("identified tf", "identified physical"))}
    met_comp = [name for name in paths
                if cell[name, label][0]["tip_mean_um"] >= 90 and cell[name, label][0]["tip_max_um"] >= 80]
    out.append(f"\nTargets (each axis's tracking error predicted within 10 % of max\\|e\\|; "
               f"90 % of the mean and 80 % of the max tip contour error removed): prediction "
               f"met on {met_prediction['identified physical']} of {len(prediction_rows)} paths "
               f"by the identified physical model and on {met_prediction['identified tf']} by "
               f"the identified `tf`; compensation with the identified model and learning met "
               f"on {len(met_comp)} of {len(paths)} paths"
               + (f" (not on {', '.join(n for n in paths if n not in met_comp)})."
                  if len(met_comp) < len(paths) else "."))
    options = [f"controller {args.controller}",
               f"learning {args.learn} pass" + ("" if args.learn == 1 else "es")]
    if args.quantize:
        options.append("quantised encoder (0.1 um / 1 urad)")
    if args.friction_mismatch:
        options.append("friction mismatch")
    key = "-".join([args.controller, f"learn{args.learn}"]
                   + (["quantize"] if args.quantize else [])
                   + (["friction-mismatch"] if args.friction_mismatch else []))
    body = "\n".join([f"## {', '.join(options).capitalize()}", "", stamp(), ""] + out)
    if args.output is None:
        print(body)
    else:
        replace_section(args.output, "intro", INTRO)
        print(f"wrote {replace_section(args.output, key, body)} (section {key})",
              file=sys.stderr)


def predict_tracking_of(traj, models) -> np.ndarray:
    from precontour.prediction import predict_tracking
    return predict_tracking(traj.t, traj.q, models)(traj.t)


if __name__ == "__main__":
    main()
