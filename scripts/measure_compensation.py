"""Measure contour-error reductions on the virtual machine for the README's table.

For each built-in path and PID controller: pre-compensate with 1 pass (the paper's procedure)
and with up to 4 passes, run the original and the compensated commands on
- the exact linear machine (continuous PID, no friction),
- the realistic machine (discrete PID at 1 kHz, friction, feed-forward friction compensation),
- the realistic machine whose true inertia J and damping B are 20 % above / below the values
  the predictor used (a mis-identified machine),
and print the reductions of max and mean tip and orientation contour errors as Markdown.
Run: ``python scripts/measure_compensation.py [PATH ...]``.
"""

from __future__ import annotations

import sys
import time

from precontour import load_machine
from precontour.trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
from precontour.compensation.precompensate import compensate
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.virtual_machine import simulate_trajectory
from precontour.trajectory.generate import generate_trajectory

MACHINES = {
    "exact": dict(mode="continuous", friction=False, ff_friction=False),
    "realistic": dict(mode="discrete", friction=True, ff_friction=True),
    "J,B +20 %": dict(mode="discrete", friction=True, ff_friction=True, inertia_scale=1.2,
                      damping_scale=1.2),
    "J,B -20 %": dict(mode="discrete", friction=True, ff_friction=True, inertia_scale=0.8,
                      damping_scale=0.8),
}
KEYS = ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")


def main(paths: list[str]) -> None:
    machine = load_machine("zhang2013")
    start = time.perf_counter()
    print("| path | controller | machine | passes | tip max um | tip mean um | ori max mrad "
          "| ori mean mrad | reduction tip max / mean % | reduction ori max / mean % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in paths:
        traj = generate_trajectory(builtin_path(path), machine)
        reference = ReferencePath.from_trajectory(traj)
        for controller in ("pid-high", "pid-low"):
            models = machine.controller(controller).error_models(machine.drives)
            compensated = {n: compensate(traj, machine.kinematics, models, iterations=n)
                           for n in (1, 4)}
            for name, options in MACHINES.items():
                def measure(q_traj):
                    sim = simulate_trajectory(q_traj, machine, controller, **options)
                    return contour_errors(reference, sim.q_act, machine.kinematics).summary()
                before = measure(traj)
                print(f"| {path} | {controller} | {name} | 0 | " +
                      " | ".join(f"{before[k]:.4g}" for k in KEYS) + " | | |")
                for n, result in compensated.items():
                    if name.startswith("J,B") and n != 1:
                        continue
                    after = measure(result.trajectory)
                    red = [100 * (1 - after[k] / before[k]) for k in KEYS]
                    print(f"| {path} | {controller} | {name} | {result.iterations} | " +
                          " | ".join(f"{after[k]:.4g}" for k in KEYS) +
                          f" | {red[0]:.1f} / {red[1]:.1f} | {red[2]:.1f} / {red[3]:.1f} |")
    print(f"\n({time.perf_counter() - start:.1f} s)", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1:] or list(BUILTIN_PATHS))
