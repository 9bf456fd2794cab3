"""Generate the built-in 'paper' trajectory, pre-compensate it, and measure the contour errors
of both commands on the virtual machine (discrete PID, friction, feed-forward).

Run: python examples/02_compensate_and_measure.py
"""

from precontour import (ReferencePath, builtin_path, compensate, contour_errors,
                        generate_trajectory, load_machine, simulate_trajectory)

machine = load_machine("zhang2013")
traj = generate_trajectory(builtin_path("paper"), machine)
reference = ReferencePath.from_trajectory(traj)
models = machine.controller("pid-high").error_models(machine.drives)
result = compensate(traj, machine.kinematics, models, reference=reference)

for label, commands in (("uncompensated", traj), ("pre-compensated", result.trajectory)):
    sim = simulate_trajectory(commands, machine, "pid-high")
    errors = contour_errors(reference, sim.q_act, machine.kinematics).summary()
    print(f"{label:>16}: tip max {errors['tip_max_um']:.2f} um, mean "
          f"{errors['tip_mean_um']:.3f} um; orientation max {errors['ori_max_mrad']:.4f} mrad")
