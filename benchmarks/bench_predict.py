"""Speed of spline fit + closed-form prediction against scipy.signal.lsim of the same loops.

For 2,500 / 25,000 / 250,000 / 1,000,000 samples of a five-axis trajectory at 1 kHz, prints
the time of fit + prediction (all five axes, errors evaluated at every sample), microseconds
per sample, knots, and the time of ``scipy.signal.lsim`` of the same five closed loops on the
same samples, measured in the same run. Run: ``python benchmarks/bench_predict.py [--quick]``.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy import signal

from precontour import load_machine
from precontour.prediction.tracking import predict_tracking


def five_axis_trajectory(n_samples: int, ts: float = 1e-3):
    """A smooth rest-to-rest five-axis motion with features every ~0.5 s."""
    t = np.arange(n_samples) * ts
    s = t / t[-1]
    ramp = 35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7
    envelope = (s * (1 - s)) ** 4 * 256
    q = np.stack([
        -40 + 80 * ramp + 5 * np.sin(2 * np.pi * 0.9 * t) * envelope,
        10 + 20 * np.sin(2 * np.pi * 0.6 * t) * envelope,
        300 - 20 * ramp + 3 * np.sin(2 * np.pi * 1.3 * t) * envelope,
        0.2 + 1.0 * ramp + 0.1 * np.sin(2 * np.pi * 0.7 * t) * envelope,
        -1.0 + 2.0 * ramp + 0.3 * np.sin(2 * np.pi * 0.5 * t) * envelope,
    ], axis=1)
    return t, q


def best_of(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def main(argv: list[str]) -> None:
    sizes = [2_500, 25_000] if "--quick" in argv else [2_500, 25_000, 250_000, 1_000_000]
    machine = load_machine("zhang2013")
    models = machine.error_models("pid-low")
    print(f"{'samples':>10} {'fit+predict s':>14} {'us/sample':>10} {'knots (X Y Z A C)':>28} "
          f"{'lsim s':>9} {'lsim/ours':>10}")
    for n in sizes:
        t, q = five_axis_trajectory(n)
        repeat = 5 if n <= 25_000 else 1

        def ours():
            prediction = predict_tracking(t, q, models)
            return prediction, prediction(t)
        seconds, (prediction, _) = best_of(ours, repeat)

        def reference():
            return [signal.lsim((m.num, m.den), q[:, i] - q[0, i], t)[1]
                    for i, m in enumerate(models)]
        lsim_seconds, _ = best_of(reference, 1 if n >= 250_000 else 3)
        knots = " ".join(str(k) for k in prediction.fits.n_knots)
        print(f"{n:>10} {seconds:>14.4f} {1e6 * seconds / n:>10.2f} {knots:>28} "
              f"{lsim_seconds:>9.3f} {lsim_seconds / seconds:>10.1f}")


if __name__ == "__main__":
    main(sys.argv[1:])
