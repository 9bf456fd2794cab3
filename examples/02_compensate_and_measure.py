"""Generate the built-in 'paper' trajectory, pre-compensate it within the machine's limits,
and measure the contour errors of both commands on the virtual machine (discrete PID,
friction, feed-forward).

Run: python examples/02_compensate_and_measure.py
"""

from precontour import (LimitOptions, builtin_path, compensate, contour_errors,
                        generate_trajectory, load_servo, simulate)

servo = load_servo("zhang2013", "pid-high")        # kinematics, drives, controller, limits
traj = generate_trajectory(builtin_path("paper"), servo.machine)
# within the limits, slowed down to half the speed at most (the default; limits=False: none);
# learn=LearningOptions(passes=4) would also learn against the virtual machine
comp = compensate(servo, traj, limits=LimitOptions(min_speed=0.5))

for label, commands in (("uncompensated", comp.reference), ("pre-compensated", comp)):
    errors = contour_errors(servo, comp.reference, simulate(servo, commands)).summary()
    print(f"{label:>16}: tip max {errors['tip_max_um']:.2f} um, mean "
          f"{errors['tip_mean_um']:.3f} um; orientation max {errors['ori_max_mrad']:.4f} mrad")
print(f"slowed in {len(comp.slowdowns)} window(s), +{comp.added_time:.3f} s")
