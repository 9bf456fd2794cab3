"""Cost per sample of the contour errors where the reference nearly rests (issue 39).

``ReferencePath.errors`` (tool tip and orientation, the reference built fresh so its sample
tree and isolation are counted) at 25,000 to 400,000 samples of two references at 1 kHz:

- *moving*: a helix at 15 mm/s, the tool tilting; the actual 2 ms behind and 3 um aside;
- *resting*: a path slowed to 1 nm per sample (1 um/s) over all but its first and last 2,000
  samples, orientation to 1e-9 rad per sample, as a heavily slowed feed near a stop; the actual
  2-8 um behind along the path and creeping 2 um aside, its orientation 1e-6 rad behind;
- *at rest*: the same with the reference standing still (the same sample repeated) over
  that stretch.

Printed per reference and size: microseconds per sample, the linearity ratio (us per sample
at this size over that at 25,000: 1 when linear) and the ratio to the moving reference at the
same size (1 when the spacing of the samples does not matter). The baseline, measured in the
same run on the same windows: a compiled brute-force scan of every window for the nearest
sample alone (threads as the search), and its ratio to the whole search.

Run: ``python benchmarks/bench_nearest.py [--quick]``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from precontour.kernels import jit, run_chunks
from precontour.prediction.contour import ReferencePath

_CHUNK = 4096


def moving(n: int):
    t = np.arange(n) * 1e-3

    def tip(time):
        phase = 2 * np.pi * 0.05 * time
        return np.stack([40 * np.cos(phase) + 0.5 * time, 40 * np.sin(phase),
                         300 - 10 * time / t[-1]], axis=1)

    def orientation(time):
        angle = 0.3 * np.sin(2 * np.pi * 0.02 * time)
        return np.stack([np.sin(angle), np.zeros_like(angle), np.cos(angle)], axis=1)

    actual = tip(t - 2e-3) + 3e-3 * np.sin(t)[:, None] / np.sqrt(3)
    return t, tip(t), orientation(t), actual, orientation(t - 2e-3)


def resting(n: int, step: float = 1e-6):
    t = np.arange(n) * 1e-3
    speed = np.full(n, step)
    speed[:2000] = np.linspace(0.05, step, 2000)
    speed[-2000:] = np.linspace(step, 0.05, 2000)
    if step == 0.0:
        speed[1999] = speed[-2000] = 0.0
    arc = np.concatenate([[0.0], np.cumsum(speed[1:])])
    direction = np.array([1.0, 0.6, -0.2]) / np.linalg.norm([1.0, 0.6, -0.2])
    origin = np.array([10.0, -5.0, 200.0])
    P = origin + arc[:, None] * direction + 1e-4 * np.sin(arc / 0.01)[:, None] * [0, 0, 1.0]
    turn = np.concatenate([[0.0], np.cumsum(np.where(speed[1:] > 1e-3, 1e-4,
                                                     1e3 * step * 1e-6))])
    angle = 0.2 + turn
    O = np.stack([np.sin(angle), np.zeros(n), np.cos(angle)], axis=1)
    lag = 5e-3 + 3e-3 * np.sin(t / 7.0)
    creep = 2e-3 * np.stack([np.sin(t / 3.0), np.cos(t / 5.0), np.sin(t / 11.0)], axis=1)
    actual = origin + (arc - lag)[:, None] * direction + creep
    behind = angle - 1e-6
    O_actual = np.stack([np.sin(behind), 1e-7 * np.sin(t), np.cos(behind)], axis=1)
    O_actual /= np.linalg.norm(O_actual, axis=1, keepdims=True)
    return t, P, O, actual, O_actual


REFERENCES = {"moving": moving, "resting": resting, "at rest": lambda n: resting(n, 0.0)}


@jit
def _brute_chunks(first, stop, samples, points, lo, hi, nearest):
    n = points.shape[0]
    for chunk in range(first, stop):
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            best = np.inf
            for j in range(lo[i], hi[i] + 1):
                s = 0.0
                for d in range(3):
                    s += (samples[j, d] - points[i, d]) ** 2
                if s < best:
                    best = s
                    nearest[i] = j


def brute_force(reference: ReferencePath, P_act, O_act) -> None:
    """The nearest tip and orientation sample of every window by scanning it."""
    _, lo, hi = reference._own_windows
    nearest = np.empty(P_act.shape[0], dtype=np.intp)
    for samples, points in ((reference.P, P_act), (reference.O, O_act)):
        run_chunks(_brute_chunks, -(-points.shape[0] // _CHUNK), np.ascontiguousarray(samples),
                   np.ascontiguousarray(points), lo, hi, nearest)


def best_of(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main(argv: list[str]) -> None:
    sizes = ([25_000, 100_000] if "--quick" in argv
             else [25_000, 50_000, 100_000, 200_000, 400_000])
    warm = moving(10_000)
    ReferencePath.from_samples(*warm[:3]).errors(*warm[3:])        # compile outside the timing
    brute_force(ReferencePath.from_samples(*warm[:3]), *warm[3:])
    print(f"{'reference':>9} {'samples':>8} {'us/sample':>10} {'vs 25k':>7} {'vs moving':>10} "
          f"{'brute us/sample':>16} {'brute/ours':>11}")
    per_sample = {}
    for name, make in REFERENCES.items():
        for n in sizes:
            t, P, O, P_act, O_act = make(n)
            repeat = 3 if n <= 100_000 else 2
            seconds = best_of(lambda: ReferencePath.from_samples(t, P, O).errors(P_act, O_act),
                              repeat)
            reference = ReferencePath.from_samples(t, P, O)
            reference._own_windows
            brute = best_of(lambda: brute_force(reference, P_act, O_act), 1)
            us = 1e6 * seconds / n
            per_sample[name, n] = us
            print(f"{name:>9} {n:>8} {us:>10.3f} {us / per_sample[name, sizes[0]]:>7.2f} "
                  f"{us / per_sample['moving', n]:>10.2f} {1e6 * brute / n:>16.3f} "
                  f"{brute / seconds:>11.1f}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
