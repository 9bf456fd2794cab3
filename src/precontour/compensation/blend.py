"""C2 blends between two commands: one command's correction left out locally and tapered.

Used where the compensated commands must give way locally, to the planned commands where they
break a limit that slowing down cannot cure (:mod:`.within_limits`), to axis tracking-error
pre-compensation at kinks of the corrections, and to a command that does not hurt where a
block's error on the machine would exceed the uncompensated one's (:mod:`.blocks`).
"""

from __future__ import annotations

import numpy as np

#: Half-width (s) around a sample over a limit where the correction is left out entirely, and
#: width (s) of the C2 taper on each side.
TAPER_HOLD = 0.05
TAPER_WIDTH = 0.1


def taper_weight(over: np.ndarray, ts: float, hold: float = TAPER_HOLD,
                 width: float = TAPER_WIDTH) -> tuple[np.ndarray, np.ndarray]:
    """Weight 1 within ``hold`` (s) of the samples ``over``, falling to 0 over ``width`` (s) on
    each side: the indicator of the widened windows smoothed by four moving averages (a cubic
    B-spline kernel: C2); exactly 1 on ``over``. Returns the weight and the widened windows
    (the indicator before smoothing)."""
    n = over.size
    hold = int(round(hold / ts))
    box = max(1, int(round(width / ts / 4)))
    # widen by the hold and by the kernel's half-support, so that the weight is 1 on ``over``
    widen = hold + 2 * box
    index = np.flatnonzero(over)
    marks = np.zeros(n + 1)
    np.add.at(marks, np.clip(index - widen, 0, n), 1.0)
    np.add.at(marks, np.clip(index + widen + 1, 0, n), -1.0)
    cut = np.cumsum(marks[:n]) > 0
    weight = cut.astype(float)
    kernel = np.ones(box) / box
    for _ in range(4):
        weight = np.convolve(np.pad(weight, (box, box), mode="edge"), kernel, mode="same")[box:-box]
    weight = np.clip(weight, 0.0, 1.0)
    weight[over] = 1.0
    return weight, cut


def taper_corrections(q_planned: np.ndarray, q_compensated: np.ndarray, over: np.ndarray,
                      ts: float, hold: float = TAPER_HOLD
                      ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Commands whose correction ``q_compensated - q_planned`` is left out around the samples
    ``over`` (within ``hold``, s; :data:`TAPER_HOLD`) and tapered in and out over
    :data:`TAPER_WIDTH`.

    The weight is :func:`taper_weight` (C2, so the taper adds bounded jerk, of the order of
    the correction over ``TAPER_WIDTH`` cubed); it is exactly 0 on the samples over a limit.
    Returns the commands and the left-out windows as sample index pairs.
    """
    weight, cut = taper_weight(over, ts, hold)
    q = q_compensated - weight[:, None] * (q_compensated - q_planned)
    # where the correction is left out wholly, the planned command to the last digit (the
    # difference above is off by round-off, and a fallback judged against the planned
    # command's own errors must not lose by one unit in the last place)
    whole = weight == 1.0
    q[whole] = q_planned[whole]
    edges = np.flatnonzero(np.diff(np.r_[0, cut.astype(np.int8), 0]))
    return q, list(zip(edges[::2], edges[1::2] - 1))


def c2_step(x: np.ndarray) -> np.ndarray:
    """C2 step from 0 (x <= 0) to 1 (x >= 1): 6x^5 - 15x^4 + 10x^3."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))
