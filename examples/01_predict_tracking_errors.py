"""Predict each axis's tracking error in closed form and check it against scipy's lsim.

Run: python examples/01_predict_tracking_errors.py
"""

from pathlib import Path

import numpy as np
from scipy import signal

from precontour import load_servo, predict, read_trajectory

servo = load_servo("zhang2013", "pid-low")
traj = read_trajectory(Path(__file__).with_name("smooth5axis.csv"))

prediction = predict(servo, traj)
e = prediction.e
print("knots per axis:", prediction.n_knots)
for i, (axis, model) in enumerate(zip(servo.axis_names, servo.models)):
    # lsim interpolates the samples linearly, the predictor follows the fitted C3 spline:
    # they agree to a fraction of a percent at 1 ms sampling
    reference = signal.lsim((model.num, model.den), traj.q[:, i] - traj.q[0, i], traj.t)[1]
    print(f"{axis}: max|e| {np.abs(e[:, i]).max():.6g}, lsim {np.abs(reference).max():.6g}, "
          f"max difference {np.abs(e[:, i] - reference).max():.2g}")
